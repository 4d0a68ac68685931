//! `radiosity view` as a process, over raw HTTP (no browser): it serves only GET/HEAD of its
//! known paths, refuses traversal (plain and percent-encoded), other methods and foreign
//! `Host` headers, listens on 127.0.0.1 only, shows saved solutions, fails on bad input
//! before serving, and stops cleanly on Ctrl-C (SIGINT).
//!
//! The server's own unit tests (`src/view/tests.rs`) go through many more malformed
//! requests; these check the same rules on the real command.

#[path = "support/viewer.rs"]
mod viewer;

use serde_json::Value;
use std::io::{Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpListener, TcpStream};
use std::process::Command;
use std::time::{Duration, Instant};

/// A small, quick solve of the built-in Cornell box.
const SMALL: &[&str] = &["--elements", "200", "-q"];

/// Sends `request` verbatim to 127.0.0.1:`port` and returns the status code and the whole
/// response (the server closes after errors; good requests ask it to close).
fn raw(port: u16, request: &str) -> (u16, String) {
    let mut s = TcpStream::connect((Ipv4Addr::LOCALHOST, port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut bytes = Vec::new();
    let _ = s.read_to_end(&mut bytes);
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let status = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {text:?}"));
    (status, text)
}

fn get(port: u16, method: &str, target: &str) -> (u16, String) {
    raw(
        port,
        &format!(
            "{method} {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
        ),
    )
}

fn body_json(response: &str) -> Value {
    let body = response.split_once("\r\n\r\n").unwrap().1;
    serde_json::from_str(body).unwrap()
}

/// Waits until `/api/progress` reports a finished solve; returns the notice.
fn wait_done(port: u16, timeout: Duration) -> Value {
    let start = Instant::now();
    loop {
        let (status, text) = get(port, "GET", "/api/progress");
        assert_eq!(status, 200);
        let notice = body_json(&text);
        if notice["progress"]["done"] == true {
            return notice;
        }
        assert!(start.elapsed() < timeout, "not done: {notice}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The listening sockets on `port` from /proc/net/tcp and tcp6 (Linux): local addresses
/// as the kernel writes them (hex).
fn listeners(port: u16) -> Vec<String> {
    let mut found = Vec::new();
    for table in ["/proc/net/tcp", "/proc/net/tcp6"] {
        let Ok(text) = std::fs::read_to_string(table) else {
            continue;
        };
        for line in text.lines().skip(1) {
            let fields: Vec<&str> = line.split_whitespace().collect();
            // Field 1 is local_address "ADDR:PORT", field 3 the state; 0A = LISTEN.
            if fields.len() > 3 && fields[3] == "0A" {
                if let Some((addr, p)) = fields[1].rsplit_once(':') {
                    if u16::from_str_radix(p, 16) == Ok(port) {
                        found.push(addr.to_owned());
                    }
                }
            }
        }
    }
    found
}

#[test]
fn serves_known_paths_to_loopback_only_and_refuses_the_rest() {
    let v = viewer::start(SMALL, Duration::from_secs(30));
    let port = v.port;
    assert_eq!(v.url, format!("http://127.0.0.1:{port}/"));

    // Listening on 127.0.0.1 only (0100007F in /proc's little-endian hex), never on
    // 0.0.0.0 or IPv6; another loopback address of the same port is refused.
    if std::path::Path::new("/proc/net/tcp").exists() {
        assert_eq!(listeners(port), vec!["0100007F".to_owned()]);
    }
    let other = SocketAddr::from(([127, 0, 0, 2], port));
    assert!(TcpStream::connect_timeout(&other, Duration::from_secs(2)).is_err());

    // The page and its embedded assets.
    let (status, page) = get(port, "GET", "/");
    assert_eq!(status, 200);
    assert!(page.contains("<script type=\"module\" src=\"/assets/viewer.js\"></script>"));
    assert!(page.contains("Content-Security-Policy: default-src 'none'"));
    for asset in [
        "viewer.js",
        "three.module.js",
        "three.core.js",
        "OrbitControls.js",
    ] {
        let (status, text) = get(port, "GET", &format!("/assets/{asset}"));
        assert_eq!(status, 200, "{asset}");
        assert!(text.contains("Content-Type: text/javascript"), "{asset}");
    }
    let (status, head) = get(port, "HEAD", "/assets/three.core.js");
    assert_eq!(status, 200);
    assert!(!head.contains("REVISION"), "HEAD sent a body");

    // Traversal, plain and encoded (once and twice), backslashes, absolute paths: nothing
    // but the fixed table is ever served, and no file is read.
    let secret = ["[package]", "fn main", "root:x:", "[workspace]"];
    for target in [
        "/../Cargo.toml",
        "/assets/../Cargo.toml",
        "/assets/../../Cargo.toml",
        "/assets/../../src/main.rs",
        "/%2e%2e/Cargo.toml",
        "/assets/%2e%2e/%2e%2e/Cargo.toml",
        "/assets/..%2f..%2fCargo.toml",
        "/assets/%252e%252e/Cargo.toml",
        "/assets/..%5c..%5cCargo.toml",
        "/assets\\..\\Cargo.toml",
        "//etc/passwd",
        "/etc/passwd",
        "/assets//etc/passwd",
        "/assets/%2fetc%2fpasswd",
        "/./assets/viewer.js",
        "/assets/./viewer.js",
        "/assets/viewer.js/..",
        "/assets/%76iewer.js",
        "/assets/",
        "/assets",
        "/index.html",
        "/api/nothing",
        "/api/",
        "/events/",
        "/favicon.ico",
        "http://127.0.0.1/../Cargo.toml",
    ] {
        let (status, text) = get(port, "GET", target);
        assert_eq!(status, 404, "{target}");
        for s in secret {
            assert!(!text.contains(s), "{target} leaked {s}");
        }
    }

    // Only GET and HEAD: other methods on known paths are 405 (with Allow), elsewhere 404.
    for method in [
        "POST", "PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "get",
    ] {
        for target in ["/", "/api/progress", "/events", "/assets/viewer.js"] {
            let (status, text) = get(port, method, target);
            assert_eq!(status, 405, "{method} {target}");
            assert!(text.contains("Allow: GET, HEAD"), "{method} {target}");
        }
        assert_eq!(get(port, method, "/nothing").0, 404, "{method}");
    }

    // Host: only this server's own names with its own port (DNS rebinding).
    let other_port = port.wrapping_add(1);
    for host in [
        "evil.example".to_owned(),
        format!("evil.example:{port}"),
        format!("127.0.0.1.evil.example:{port}"),
        format!("localhost.evil.example:{port}"),
        format!("127.0.0.1:{other_port}"),
        format!("10.0.0.1:{port}"),
        "127.0.0.1".to_owned(),
    ] {
        for target in ["/", "/api/mesh", "/events"] {
            let (status, _) = raw(
                port,
                &format!("GET {target} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
            );
            assert_eq!(status, 403, "Host {host} on {target}");
        }
    }
    for host in [format!("localhost:{port}"), format!("[::1]:{port}")] {
        let (status, _) = raw(
            port,
            &format!("GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
        );
        assert_eq!(status, 200, "Host {host}");
    }
    assert_eq!(
        raw(port, "GET / HTTP/1.1\r\nConnection: close\r\n\r\n").0,
        400
    );

    // The solve ends converged; its mesh and frame are served.
    let notice = wait_done(port, Duration::from_secs(60));
    assert_eq!(notice["progress"]["status"], "converged", "{notice}");
    let (status, mesh) = get(port, "GET", "/api/mesh");
    assert_eq!(status, 200);
    assert!(mesh.contains("RVW1"));

    // Ctrl-C: exit status 0 within a few seconds, and the port is closed.
    let (status, took, stderr) = v.interrupt(Duration::from_secs(10));
    assert!(status.success(), "{status}: {stderr}");
    assert!(took < Duration::from_secs(3), "{took:?}");
    assert!(TcpStream::connect((Ipv4Addr::LOCALHOST, port)).is_err());
}

#[test]
fn shows_a_saved_solution_without_solving() {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("box.solution.json");
    let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["solve", "--elements", "200", "-q", "--save"])
        .arg(&saved)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let file: Value = serde_json::from_str(&std::fs::read_to_string(&saved).unwrap()).unwrap();

    let v = viewer::start(
        &["--solution", saved.to_str().unwrap(), "-q"],
        Duration::from_secs(30),
    );
    let notice = wait_done(v.port, Duration::from_secs(10));
    assert_eq!(notice["progress"]["status"], "loaded");
    assert!(notice["progress"]["message"]
        .as_str()
        .unwrap()
        .contains("box.solution.json"));
    // The frame carries the file's radiosity and irradiance (as f32), the mesh its names.
    let frame = body_json(&get(v.port, "GET", "/api/frame?format=json").1);
    for key in ["radiosity", "irradiance"] {
        let ours = frame[format!("element_{key}")].as_array().unwrap();
        let theirs = file[key].as_array().unwrap();
        assert_eq!(ours.len(), theirs.len());
        for (a, b) in ours.iter().zip(theirs) {
            for c in 0..3 {
                let (a, b) = (a[c].as_f64().unwrap(), b[c].as_f64().unwrap());
                assert!(
                    (a - b).abs() <= 1e-6 * b.abs().max(1.0),
                    "{key}: {a} vs {b}"
                );
            }
        }
    }
    let mesh = body_json(&get(v.port, "GET", "/api/mesh?format=json").1);
    assert_eq!(mesh["object_names"], file["objects"]);
    assert_eq!(
        mesh["element_object"].as_array().unwrap().len(),
        file["elements"].as_array().unwrap().len()
    );
    let (status, _, _) = v.interrupt(Duration::from_secs(10));
    assert!(status.success());
}

#[test]
fn bad_input_fails_before_anything_is_served() {
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .arg("view")
            .args(args)
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, stdout, stderr) = run(&["no-such-scene.obj"]);
    assert_eq!(code, Some(1));
    assert!(stdout.is_empty(), "a URL was printed: {stdout}");
    assert!(stderr.contains("no-such-scene.obj"), "{stderr}");

    let (code, stdout, stderr) = run(&["--solution", "no-such-solution.json"]);
    assert_eq!(code, Some(1));
    assert!(stdout.is_empty());
    assert!(stderr.contains("no-such-solution.json"), "{stderr}");

    let (code, stdout, stderr) = run(&["--elements", "-5"]);
    assert_eq!(code, Some(1));
    assert!(stdout.is_empty());
    assert!(stderr.contains("--elements"), "{stderr}");

    let (code, _, stderr) = run(&["--port", "70000"]);
    assert_eq!(code, Some(1));
    assert!(stderr.contains("--port"), "{stderr}");

    // A port already taken: the error names the address.
    let taken = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
    let port = taken.local_addr().unwrap().port();
    let (code, stdout, stderr) = run(&["--port", &port.to_string(), "-q"]);
    assert_eq!(code, Some(1));
    assert!(stdout.is_empty());
    assert!(stderr.contains(&format!("127.0.0.1:{port}")), "{stderr}");
}

#[test]
fn waits_for_a_page_then_solves_and_ctrl_c_stops_a_running_solve() {
    // --wait: nothing is solved until a page opens the event stream. (Progressive
    // refinement: its mesh is shown before the form factors.)
    let v = viewer::start(
        &["--wait", "--solver", "progressive", "--elements", "200"],
        Duration::from_secs(30),
    );
    std::thread::sleep(Duration::from_millis(500));
    let notice = body_json(&get(v.port, "GET", "/api/progress").1);
    assert_eq!(
        notice["progress"]["stage"], "waiting for a page to connect",
        "{notice}"
    );
    // The meshed scene is already shown (its emitters), before any solving.
    assert_eq!(notice["mesh_version"], 1);
    let mut events = TcpStream::connect((Ipv4Addr::LOCALHOST, v.port)).unwrap();
    let request = format!("GET /events HTTP/1.1\r\nHost: localhost:{}\r\n\r\n", v.port);
    events.write_all(request.as_bytes()).unwrap();
    let notice = wait_done(v.port, Duration::from_secs(60));
    assert_eq!(notice["progress"]["status"], "converged");
    // The event stream saw notices.
    events
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let mut buf = [0u8; 4096];
    let n = events.read(&mut buf).unwrap();
    let text = String::from_utf8_lossy(&buf[..n]);
    assert!(text.starts_with("HTTP/1.1 200 OK"), "{text}");
    assert!(text.contains("text/event-stream"), "{text}");
    let (status, _, stderr) = v.interrupt(Duration::from_secs(10));
    assert!(status.success(), "{stderr}");
    assert!(stderr.contains("converged"), "{stderr}");

    // Ctrl-C in the middle of a long solve ends the command at once, with status 0. (The
    // default solve of the Cornell box, 0.2–0.3 s now, can be over before the progress is
    // asked for; ε = 0.00025 takes 2.9 s on the 2-core machine.)
    let v = viewer::start(&["-q", "--epsilon", "0.00025"], Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let notice = body_json(&get(v.port, "GET", "/api/progress").1);
    assert_eq!(notice["progress"]["done"], false, "{notice}");
    let (status, took, stderr) = v.interrupt(Duration::from_secs(10));
    assert!(status.success(), "{status}: {stderr}");
    assert!(took < Duration::from_secs(2), "{took:?}");
}
