//! Tests of the viewer's server over real sockets: what it serves, what it refuses, its
//! limits, its event stream and its shutdown. Requests are written byte for byte, so that
//! malformed and hostile ones reach the server exactly as an attacker would send them.

use super::protocol::{encode_frame, encode_mesh, StateNotice, ViewStatus};
use super::server::RunningServer;
use super::test_scene::{box_mesh, uniform_frame};
use super::*;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Starts a server on a free port with the 2 × 2 box mesh and one frame.
fn start(config: ServerConfig) -> (Arc<ViewState>, RunningServer) {
    let state = Arc::new(ViewState::new());
    let mesh = box_mesh(2, 1);
    let frame = uniform_frame(&mesh, 1, &[[0.1, 0.2, 0.3]; 8], &[[1.0, 2.0, 3.0]; 8]);
    state.set_mesh(mesh).unwrap();
    state.set_frame(frame).unwrap();
    let server = Server::bind(state.clone(), config).unwrap();
    (state, server.spawn().unwrap())
}

fn start_default() -> (Arc<ViewState>, RunningServer) {
    start(ServerConfig::default())
}

struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Reply {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

/// Parses one response from the front of `raw`; returns it and the bytes after it.
fn parse_reply(raw: &[u8], head_only: bool) -> (Reply, usize) {
    let end = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a complete response head")
        + 4;
    let head = std::str::from_utf8(&raw[..end]).unwrap();
    let mut lines = head.trim_end().split("\r\n");
    let status_line = lines.next().unwrap();
    assert!(status_line.starts_with("HTTP/1.1 "), "{status_line}");
    let status = status_line[9..12].parse().unwrap();
    let headers: Vec<(String, String)> = lines
        .map(|l| {
            let (n, v) = l.split_once(": ").unwrap();
            (n.to_owned(), v.to_owned())
        })
        .collect();
    let length: usize = headers
        .iter()
        .find(|(n, _)| n == "Content-Length")
        .map(|(_, v)| v.parse().unwrap())
        .unwrap_or(0);
    let body_len = if head_only { 0 } else { length };
    assert!(raw.len() >= end + body_len, "truncated body");
    let body = raw[end..end + body_len].to_vec();
    (
        Reply {
            status,
            headers,
            body,
        },
        end + body_len,
    )
}

/// Sends `request` as is and reads until the server closes the connection.
fn exchange(addr: SocketAddr, request: &[u8]) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(request).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out)
        .expect("the server closes the connection in time");
    out
}

fn raw(addr: SocketAddr, request: &str) -> Reply {
    let bytes = exchange(addr, request.as_bytes());
    parse_reply(&bytes, request.starts_with("HEAD ")).0
}

fn request(addr: SocketAddr, method: &str, target: &str) -> Reply {
    let port = addr.port();
    raw(
        addr,
        &format!(
            "{method} {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
        ),
    )
}

fn get(addr: SocketAddr, target: &str) -> Reply {
    request(addr, "GET", target)
}

#[test]
fn binds_to_loopback_only() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    assert_eq!(addr.ip(), std::net::Ipv4Addr::LOCALHOST);
    assert_ne!(addr.port(), 0, "port 0 picks a free port");
    assert_eq!(server.url(), format!("http://127.0.0.1:{}/", addr.port()));
    // Nothing listens on the same port of the IPv6 loopback or of 127.0.0.2 (another
    // loopback address the server would answer on had it bound 0.0.0.0).
    let v6 = SocketAddr::from((std::net::Ipv6Addr::LOCALHOST, addr.port()));
    assert!(TcpStream::connect_timeout(&v6, Duration::from_secs(1)).is_err());
    let other = SocketAddr::from(([127, 0, 0, 2], addr.port()));
    assert!(TcpStream::connect_timeout(&other, Duration::from_secs(1)).is_err());
    server.stop().unwrap();
}

#[test]
fn serves_the_page_and_every_asset() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    let page = get(addr, "/");
    assert_eq!(page.status, 200);
    assert_eq!(
        page.header("Content-Type"),
        Some("text/html; charset=utf-8")
    );
    assert_eq!(page.body, assets::INDEX.bytes);
    let csp = page.header("Content-Security-Policy").unwrap();
    assert!(csp.contains("default-src 'none'") && csp.contains(assets::IMPORT_MAP_SHA256));
    assert_eq!(page.header("X-Content-Type-Options"), Some("nosniff"));
    for a in assets::ASSETS {
        let r = get(addr, &format!("/assets/{}", a.name));
        assert_eq!(r.status, 200, "{}", a.name);
        assert_eq!(r.body, a.bytes, "{}", a.name);
        assert_eq!(r.header("Content-Type"), Some(a.content_type));
        let h = request(addr, "HEAD", &format!("/assets/{}", a.name));
        assert_eq!(h.status, 200);
        assert_eq!(
            h.header("Content-Length"),
            Some(a.bytes.len().to_string().as_str())
        );
        assert!(h.body.is_empty());
    }
    // A query string does not change which file is served.
    assert_eq!(get(addr, "/?mode=flat&ui=0").body, assets::INDEX.bytes);
    server.stop().unwrap();
}

#[test]
fn serves_mesh_frame_and_progress() {
    let (state, server) = start_default();
    let addr = server.local_addr();
    let mesh = get(addr, "/api/mesh");
    assert_eq!(mesh.status, 200);
    assert_eq!(
        mesh.header("Content-Type"),
        Some("application/octet-stream")
    );
    assert_eq!(mesh.body, encode_mesh(&state.mesh().unwrap()));
    let json = get(addr, "/api/mesh?format=json");
    let back: ViewMesh = serde_json::from_slice(&json.body).unwrap();
    assert_eq!(back, *state.mesh().unwrap());
    let frame = get(addr, "/api/frame");
    assert_eq!(frame.body, encode_frame(&state.frame().unwrap()));
    let back: ViewFrame =
        serde_json::from_slice(&get(addr, "/api/frame?format=json").body).unwrap();
    assert_eq!(back, *state.frame().unwrap());
    state.finish(Outcome::Stopped("stopped at the shot limit".to_owned()));
    let progress: StateNotice = serde_json::from_slice(&get(addr, "/api/progress").body).unwrap();
    assert_eq!(progress.progress.status, ViewStatus::Stopped);
    assert_eq!(progress.progress.message, "stopped at the shot limit");
    assert_eq!((progress.mesh_version, progress.frame), (Some(1), Some(1)));
    server.stop().unwrap();
}

#[test]
fn no_mesh_or_frame_yet_is_not_found() {
    let state = Arc::new(ViewState::new());
    let server = Server::bind(state, ServerConfig::default())
        .unwrap()
        .spawn()
        .unwrap();
    let addr = server.local_addr();
    for path in ["/api/mesh", "/api/frame", "/api/mesh?format=json"] {
        assert_eq!(get(addr, path).status, 404, "{path}");
    }
    assert_eq!(get(addr, "/api/progress").status, 200);
    server.stop().unwrap();
}

#[test]
fn path_traversal_never_reaches_a_file() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    let secrets = [&b"[package]"[..], b"root:", b"fn main"];
    for target in [
        "/../Cargo.toml",
        "/assets/../Cargo.toml",
        "/assets/../../Cargo.toml",
        "/assets/..%2fCargo.toml",
        "/assets/..%2FCargo.toml",
        "/assets/%2e%2e/%2e%2e/Cargo.toml",
        "/assets/%2e%2e%2f%2e%2e%2fCargo.toml",
        "/assets/%252e%252e%252fCargo.toml",
        "/assets/%c0%ae%c0%ae/Cargo.toml",
        "/assets/..\\..\\Cargo.toml",
        "/assets/..%5c..%5cCargo.toml",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/../../../../etc/passwd",
        "//etc/passwd",
        "/assets//etc/passwd",
        "/assets/./viewer.js",
        "/assets//viewer.js",
        "/assets/viewer.js/",
        "/assets/viewer.js/..",
        "/assets/viewer.js%00",
        "/assets/viewer%2ejs",
        "/assets/VIEWER.JS",
        "/assets/../src/view/server.rs",
        "/./",
        "/index.html",
        "/assets/index.html",
        "/assets/",
        "/assets",
        "/api/",
        "/api/mesh/",
        "/api/mesh/../frame",
        "/events/",
        "/favicon.ico",
        "/.git/config",
        "http://127.0.0.1/etc/passwd",
        "*",
    ] {
        let r = get(addr, target);
        assert_eq!(r.status, 404, "{target}");
        assert!(
            secrets
                .iter()
                .all(|s| !r.body.windows(s.len()).any(|w| w == *s)),
            "{target} leaked a file"
        );
        assert!(r.body.len() < 64, "{target}: an error body, not a listing");
    }
    server.stop().unwrap();
}

#[test]
fn only_get_and_head_are_allowed() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    for method in [
        "POST", "PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "get", "BREW",
    ] {
        for path in ["/", "/api/mesh", "/events", "/assets/viewer.js"] {
            let r = request(addr, method, path);
            assert_eq!(r.status, 405, "{method} {path}");
            assert_eq!(r.header("Allow"), Some("GET, HEAD"));
        }
        assert_eq!(
            request(addr, method, "/nothing").status,
            404,
            "{method} /nothing"
        );
    }
    // A body is refused outright, whatever the method.
    let port = addr.port();
    let post = raw(
        addr,
        &format!(
            "POST /api/mesh HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: 5\r\n\r\nhello"
        ),
    );
    assert_eq!(post.status, 413);
    let chunked = raw(
        addr,
        &format!("GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n"),
    );
    assert_eq!(chunked.status, 413);
    server.stop().unwrap();
}

#[test]
fn foreign_host_headers_are_forbidden() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    let port = addr.port();
    let with_host = |host: &str| {
        raw(
            addr,
            &format!("GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
        )
        .status
    };
    for host in [
        "evil.example".to_owned(),
        format!("evil.example:{port}"),
        format!("localhost.evil.example:{port}"),
        format!("127.0.0.1.nip.io:{port}"),
        format!("127.0.0.1:{}", port.wrapping_add(1)),
        "127.0.0.1".to_owned(),
        "localhost".to_owned(),
        format!("0.0.0.0:{port}"),
        format!("192.168.1.10:{port}"),
    ] {
        assert_eq!(with_host(&host), 403, "{host}");
    }
    for host in [
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        format!("[::1]:{port}"),
    ] {
        assert_eq!(with_host(&host), 200, "{host}");
    }
    // No Host at all, or two of them: 400 (RFC 9112 §3.2).
    assert_eq!(
        raw(addr, "GET / HTTP/1.1\r\nConnection: close\r\n\r\n").status,
        400
    );
    let two = format!("GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nHost: evil.example\r\n\r\n");
    assert_eq!(raw(addr, &two).status, 400);
    // The event stream checks the host too.
    let events = format!("GET /events HTTP/1.1\r\nHost: evil.example:{port}\r\n\r\n");
    assert_eq!(raw(addr, &events).status, 403);
    server.stop().unwrap();
}

#[test]
fn malformed_and_oversized_requests_are_refused() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    let port = addr.port();
    assert_eq!(raw(addr, "GARBAGE\r\n\r\n").status, 400);
    assert_eq!(
        raw(
            addr,
            &format!("GET / HTTP/2.0\r\nHost: 127.0.0.1:{port}\r\n\r\n")
        )
        .status,
        505
    );
    let long = "x".repeat(http::MAX_HEAD);
    let big = format!("GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Long: {long}\r\n\r\n");
    assert_eq!(raw(addr, &big).status, 431);
    // A head that never ends is cut off at the size limit, not read forever.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let endless = vec![b'a'; 4 * http::MAX_HEAD];
    let _ = s.write_all(b"GET /");
    let _ = s.write_all(&endless);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    assert!(
        out.starts_with(b"HTTP/1.1 431 "),
        "{:?}",
        String::from_utf8_lossy(&out)
    );
    server.stop().unwrap();
}

#[test]
fn slow_clients_time_out() {
    let (_state, server) = start(ServerConfig {
        io_timeout: Duration::from_millis(300),
        idle_timeout: Duration::from_millis(300),
        ..ServerConfig::default()
    });
    let addr = server.local_addr();
    // Half a request head, then silence: 408 and close after io_timeout.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let t = Instant::now();
    s.write_all(b"GET / HTTP/1.1\r\nHost: 127.").unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    assert!(out.starts_with(b"HTTP/1.1 408 "));
    // 300 ms timeout; the upper bound allows for a loaded 2-core test machine.
    let took = t.elapsed();
    assert!(
        took >= Duration::from_millis(250) && took < Duration::from_secs(3),
        "{took:?}"
    );
    // An idle connection is closed quietly after idle_timeout.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    assert!(out.is_empty());
    server.stop().unwrap();
}

#[test]
fn keep_alive_and_pipelining() {
    let (_state, server) = start_default();
    let addr = server.local_addr();
    let port = addr.port();
    let one = format!("GET /api/progress HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n");
    let last = format!(
        "HEAD /assets/style.css HTTP/1.1\r\nHost: localhost:{port}\r\nConnection: close\r\n\r\n"
    );
    let bytes = exchange(addr, format!("{one}{one}{last}").as_bytes());
    let (a, n1) = parse_reply(&bytes, false);
    let (b, n2) = parse_reply(&bytes[n1..], false);
    let (c, n3) = parse_reply(&bytes[n1 + n2..], true);
    assert_eq!((a.status, b.status, c.status), (200, 200, 200));
    assert_eq!(a.header("Connection"), Some("keep-alive"));
    assert_eq!(c.header("Connection"), Some("close"));
    assert_eq!(n1 + n2 + n3, bytes.len(), "nothing after the last response");
    server.stop().unwrap();
}

#[test]
fn connections_are_bounded() {
    let (_state, server) = start(ServerConfig {
        max_connections: 4,
        ..ServerConfig::default()
    });
    let addr = server.local_addr();
    let idle: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(addr).unwrap()).collect();
    // Let the server accept and register the four.
    std::thread::sleep(Duration::from_millis(300));
    let r = get(addr, "/api/progress");
    assert_eq!(r.status, 503);
    assert_eq!(r.header("Retry-After"), Some("1"));
    drop(idle);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        std::thread::sleep(Duration::from_millis(50));
        if get(addr, "/api/progress").status == 200 {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "slots are freed when clients leave"
        );
    }
    server.stop().unwrap();
}

/// Reads server-sent events from a stream, one `data:` payload at a time.
struct Events {
    stream: TcpStream,
    buf: Vec<u8>,
}

impl Events {
    fn open(addr: SocketAddr) -> (Self, Reply) {
        let mut stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_millis(100)))
            .unwrap();
        let port = addr.port();
        stream
            .write_all(format!("GET /events HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n").as_bytes())
            .unwrap();
        let mut events = Self {
            stream,
            buf: Vec::new(),
        };
        let deadline = Instant::now() + Duration::from_secs(5);
        let end = loop {
            if let Some(p) = events.buf.windows(4).position(|w| w == b"\r\n\r\n") {
                break p + 4;
            }
            assert!(events.fill(deadline), "no response head");
        };
        let (reply, _) = parse_reply(&events.buf[..end], true);
        events.buf.drain(..end);
        (events, reply)
    }

    /// Reads more bytes; false at end of stream or deadline.
    fn fill(&mut self, deadline: Instant) -> bool {
        let mut chunk = [0u8; 4096];
        while Instant::now() < deadline {
            match self.stream.read(&mut chunk) {
                Ok(0) => return false,
                Ok(n) => {
                    self.buf.extend_from_slice(&chunk[..n]);
                    return true;
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(_) => return false,
            }
        }
        false
    }

    /// The next `state` event's notice, or None at end of stream or after `timeout`.
    fn next(&mut self, timeout: Duration) -> Option<StateNotice> {
        let deadline = Instant::now() + timeout;
        loop {
            while let Some(p) = self.buf.windows(2).position(|w| w == b"\n\n") {
                let block = String::from_utf8(self.buf.drain(..p + 2).collect()).unwrap();
                if block.starts_with("event: state\n") {
                    let data = block
                        .lines()
                        .find_map(|l| l.strip_prefix("data: "))
                        .unwrap();
                    return Some(serde_json::from_str(data).unwrap());
                }
            }
            if !self.fill(deadline) {
                return None;
            }
        }
    }
}

#[test]
fn events_announce_new_frames() {
    let (state, server) = start_default();
    let addr = server.local_addr();
    let (mut events, head) = Events::open(addr);
    assert_eq!(head.status, 200);
    assert_eq!(head.header("Content-Type"), Some("text/event-stream"));
    // The current state comes at once.
    let first = events
        .next(Duration::from_secs(5))
        .expect("an initial notice");
    assert_eq!((first.mesh_version, first.frame), (Some(1), Some(1)));
    let mesh = state.mesh().unwrap();
    let t = Instant::now();
    state
        .set_frame(uniform_frame(&mesh, 2, &[[0.5; 3]; 8], &[[1.0; 3]; 8]))
        .unwrap();
    let next = events
        .next(Duration::from_secs(5))
        .expect("a notice after set_frame");
    assert_eq!(next.frame, Some(2));
    assert!(next.revision > first.revision);
    // Within an event interval (250 ms) plus scheduling slack on a busy machine.
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    // The frame it announces is the one served.
    assert_eq!(
        get(addr, "/api/frame").body,
        encode_frame(&state.frame().unwrap())
    );
    server.stop().unwrap();
    // Shutdown ends the stream.
    assert!(events.next(Duration::from_secs(2)).is_none());
}

#[test]
fn events_coalesce_bursts() {
    let (state, server) = start(ServerConfig {
        event_interval: Duration::from_millis(200),
        ..ServerConfig::default()
    });
    let (mut events, _) = Events::open(server.local_addr());
    events.next(Duration::from_secs(5)).unwrap();
    // 2000 updates over about a second.
    let t = Instant::now();
    for i in 0..2000u64 {
        state.set_progress(ViewProgress {
            steps: i,
            ..ViewProgress::stage("solving")
        });
        if i % 100 == 0 {
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    state.finish(Outcome::Converged);
    let burst = t.elapsed();
    let mut received = Vec::new();
    while let Some(n) = events.next(Duration::from_millis(800)) {
        let done = n.progress.done;
        received.push(n);
        if done {
            break;
        }
    }
    let last = received.last().expect("notices during the burst");
    assert_eq!(
        last.progress.message, "converged",
        "the final state always arrives"
    );
    // One notice per 200 ms interval at most, plus the one in flight at each end.
    let bound = (burst.as_secs_f64() / 0.2).ceil() as usize + 2;
    assert!(
        received.len() <= bound,
        "{} notices in {burst:?}",
        received.len()
    );
    server.stop().unwrap();
}

#[test]
fn event_streams_are_bounded() {
    let (_state, server) = start(ServerConfig {
        max_event_streams: 2,
        ..ServerConfig::default()
    });
    let addr = server.local_addr();
    let (_a, ha) = Events::open(addr);
    let (_b, hb) = Events::open(addr);
    let (_c, hc) = Events::open(addr);
    assert_eq!((ha.status, hb.status, hc.status), (200, 200, 503));
    // Ordinary requests still go through.
    assert_eq!(get(addr, "/api/progress").status, 200);
    server.stop().unwrap();
}

#[test]
fn shutdown_is_clean_and_prompt() {
    let (state, server) = start_default();
    let addr = server.local_addr();
    let handle = server.shutdown_handle();
    // Keep the server busy: two event streams, an idle keep-alive connection and a client
    // that has sent half a request.
    let (mut e1, _) = Events::open(addr);
    let (mut e2, _) = Events::open(addr);
    e1.next(Duration::from_secs(5)).unwrap();
    e2.next(Duration::from_secs(5)).unwrap();
    let mut idle = TcpStream::connect(addr).unwrap();
    let mut half = TcpStream::connect(addr).unwrap();
    half.write_all(b"GET /api/mesh HTTP/1.1\r\nHost: 127.0.0.1")
        .unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let t = Instant::now();
    handle.shutdown();
    assert!(handle.is_shutdown());
    server.join().unwrap();
    // The accept loop polls every 50 ms and connection threads every 200 ms at most;
    // 1.5 s leaves room for a loaded machine.
    let took = t.elapsed();
    assert!(took < Duration::from_millis(1500), "shutdown took {took:?}");
    // Every connection was closed by the server.
    assert!(e1.next(Duration::from_secs(2)).is_none());
    assert!(e2.next(Duration::from_secs(2)).is_none());
    for s in [&mut idle, &mut half] {
        s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let mut buf = Vec::new();
        assert!(s.read_to_end(&mut buf).is_ok(), "closed, not timed out");
    }
    // The port is closed.
    assert!(TcpStream::connect_timeout(&addr, Duration::from_secs(1)).is_err());
    // The state is still usable (the solver may keep calling it after the server stopped).
    state.set_progress(ViewProgress::stage("solving"));
    state.finish(Outcome::Converged);
}

#[test]
fn shutdown_of_an_idle_server_is_prompt() {
    let state = Arc::new(ViewState::new());
    let server = Server::bind(state, ServerConfig::default()).unwrap();
    let handle = server.shutdown_handle();
    let t0 = Instant::now();
    let thread = std::thread::spawn(move || server.run());
    std::thread::sleep(Duration::from_millis(100));
    let t = Instant::now();
    handle.shutdown();
    thread.join().unwrap().unwrap();
    assert!(
        t.elapsed() < Duration::from_millis(500),
        "{:?}",
        t.elapsed()
    );
    assert!(t0.elapsed() < Duration::from_secs(2));
}

#[test]
fn port_in_use_is_an_error_naming_the_port() {
    let (_state, server) = start_default();
    let port = server.local_addr().port();
    let e = Server::bind(
        Arc::new(ViewState::new()),
        ServerConfig {
            port,
            ..ServerConfig::default()
        },
    )
    .err()
    .expect("a second server cannot bind the same port");
    assert!(e.to_string().contains(&format!("127.0.0.1:{port}")), "{e}");
    server.stop().unwrap();
}
