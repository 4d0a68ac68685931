//! Headless Chromium for tests of the live viewer: open a page, wait until it has settled,
//! take a PNG screenshot of the window, evaluate script, click.
//!
//! Talks the Chrome DevTools Protocol (CDP) over `--remote-debugging-pipe`: JSON messages,
//! each ended by a NUL byte, the browser reading commands from its file descriptor 3 and
//! writing replies and events to descriptor 4. The descriptors are two named pipes
//! (`mkfifo`) that `sh` opens for the browser, so no WebSocket client, no unsafe code and no
//! crate beyond `serde_json` is needed. Unix only (Linux's FIFOs may be opened read-write,
//! which never blocks; that is how this side opens both ends).
//!
//! WebGL in headless Chromium without a GPU runs on SwiftShader, which must be asked for:
//! `--use-angle=swiftshader --enable-unsafe-swiftshader`. `--force-color-profile=srgb`
//! keeps the screenshot's bytes equal to what the page drew.
//!
//! Typical use:
//!
//! ```ignore
//! let Some(chromium) = headless::find_chromium() else { return }; // or fail in CI
//! let capture = headless::capture(&url, Path::new("view.png"), &headless::Options {
//!     width: 640, height: 480, budget: Duration::from_secs(60), chromium: Some(chromium),
//! })?;
//! assert_eq!(capture.status, "converged");
//! ```

#![allow(dead_code)]

use serde_json::{json, Value};
use std::collections::VecDeque;
use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// What [`capture`] needs.
#[derive(Debug, Clone)]
pub struct Options {
    /// Window (viewport) width, CSS pixels; the screenshot has this many pixels
    /// (device scale factor 1).
    pub width: u32,
    /// Window height.
    pub height: u32,
    /// Longest wait for the page to settle, from the start of navigation.
    pub budget: Duration,
    /// The browser; `None` looks for one with [`find_chromium`].
    pub chromium: Option<PathBuf>,
}

/// What the page said when it was captured.
#[derive(Debug, Clone)]
pub struct Capture {
    /// `document.body.dataset.status`: `converged`, `stopped`, `failed`, … .
    pub status: String,
    /// The `#status` element's text (exactly `converged` for a converged solve).
    pub status_text: String,
    /// `document.body.dataset.frame`: the frame number on screen.
    pub frame: Option<u64>,
    /// Time from navigation to settling.
    pub settled_after: Duration,
    /// Script errors and console errors the page reported.
    pub errors: Vec<String>,
    /// The screenshot, PNG.
    pub png: Vec<u8>,
}

/// The Chromium to use: `$CHROMIUM` if set, else the first of `chromium`,
/// `chromium-browser`, `google-chrome` found on `PATH`.
pub fn find_chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |dir| dir.join(name)))
        .find(|p| p.is_file())
}

/// [`find_chromium`] for a test in `test` (its module path): when none is found, a note
/// on stderr (past the harness's capture, so that a skip is seen) and `None`; a failure
/// instead when `RADIOSITY_REQUIRE_BROWSER` is set (CI, which installs Debian's chromium).
pub fn chromium_or_skip(test: &str) -> Option<PathBuf> {
    let found = find_chromium();
    if found.is_none() {
        assert!(
            std::env::var_os("RADIOSITY_REQUIRE_BROWSER").is_none(),
            "RADIOSITY_REQUIRE_BROWSER is set but no chromium was found (set CHROMIUM)"
        );
        let _ = writeln!(
            std::io::stderr(),
            "{test}: skipped, no chromium found (install Debian's chromium or set CHROMIUM; \
             RADIOSITY_REQUIRE_BROWSER=1 makes this a failure)"
        );
    }
    found
}

/// Opens `url` at `width` × `height`, waits (at most `budget`) until the page's
/// `data-settled` is `true` (the solve has ended and its last frame is drawn), and writes a
/// PNG screenshot to `png` (through a temporary name, renamed when complete).
pub fn capture(url: &str, png: &Path, options: &Options) -> Result<Capture, String> {
    let mut browser = Browser::launch(options)?;
    browser.navigate(url)?;
    let started = Instant::now();
    let (status, status_text, frame) = browser.wait_settled(options.budget)?;
    let settled_after = started.elapsed();
    let image = browser.screenshot()?;
    let tmp = png.with_extension("png.part");
    std::fs::write(&tmp, &image).map_err(|e| format!("writing {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, png).map_err(|e| format!("renaming to {}: {e}", png.display()))?;
    let errors = browser.errors();
    browser.close();
    Ok(Capture {
        status,
        status_text,
        frame,
        settled_after,
        errors,
        png: image,
    })
}

/// A running headless Chromium with one page attached.
pub struct Browser {
    child: Child,
    to_browser: File,
    from_browser: Receiver<Value>,
    pending: VecDeque<Value>,
    next_id: u64,
    session: String,
    errors: Vec<String>,
    dir: PathBuf,
}

impl Browser {
    /// Starts the browser and opens a blank page of the given size.
    pub fn launch(options: &Options) -> Result<Self, String> {
        let chromium = match &options.chromium {
            Some(p) => p.clone(),
            None => find_chromium().ok_or("no chromium found (set CHROMIUM)")?,
        };
        let dir = unique_dir()?;
        let (cmd_fifo, reply_fifo) = (dir.join("cdp-in"), dir.join("cdp-out"));
        for fifo in [&cmd_fifo, &reply_fifo] {
            let ok = Command::new("mkfifo")
                .arg(fifo)
                .status()
                .map_err(|e| format!("running mkfifo: {e}"))?
                .success();
            if !ok {
                return Err(format!("mkfifo {} failed", fifo.display()));
            }
        }
        // Read-write opens of a FIFO never block on Linux; the browser's own opens (by sh)
        // then find the other end already open.
        let open = |p: &Path| {
            OpenOptions::new()
                .read(true)
                .write(true)
                .open(p)
                .map_err(|e| format!("opening {}: {e}", p.display()))
        };
        let to_browser = open(&cmd_fifo)?;
        let from_fifo = open(&reply_fifo)?;
        let profile = dir.join("profile");
        let child = Command::new("sh")
            .arg("-c")
            .arg(r#"exec "$@" 3<"$CDP_IN" 4>"$CDP_OUT""#)
            .arg("sh")
            .arg(&chromium)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader",
                "--disable-quic",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding",
                "--disable-backgrounding-occluded-windows",
                "--force-color-profile=srgb",
                "--hide-scrollbars",
                "--mute-audio",
                "--remote-debugging-pipe",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(format!(
                "--window-size={},{}",
                options.width, options.height
            ))
            .arg("about:blank")
            .env("CDP_IN", &cmd_fifo)
            .env("CDP_OUT", &reply_fifo)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("starting {}: {e}", chromium.display()))?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut reader = BufReader::new(from_fifo);
            let mut message = Vec::new();
            loop {
                message.clear();
                match reader.read_until(0, &mut message) {
                    Ok(0) | Err(_) => return,
                    Ok(_) => {
                        message.pop();
                        if let Ok(v) = serde_json::from_slice::<Value>(&message) {
                            if tx.send(v).is_err() {
                                return;
                            }
                        }
                    }
                }
            }
        });
        let mut browser = Self {
            child,
            to_browser,
            from_browser: rx,
            pending: VecDeque::new(),
            next_id: 0,
            session: String::new(),
            errors: Vec::new(),
            dir,
        };
        let target =
            browser.call_browser("Target.createTarget", json!({ "url": "about:blank" }))?;
        let target_id = target["targetId"].as_str().ok_or("no targetId")?.to_owned();
        let attached = browser.call_browser(
            "Target.attachToTarget",
            json!({ "targetId": target_id, "flatten": true }),
        )?;
        browser.session = attached["sessionId"]
            .as_str()
            .ok_or("no sessionId")?
            .to_owned();
        for method in ["Page.enable", "Runtime.enable", "Log.enable"] {
            browser.call(method, json!({}))?;
        }
        browser.call(
            "Emulation.setDeviceMetricsOverride",
            json!({
                "width": options.width,
                "height": options.height,
                "deviceScaleFactor": 1,
                "mobile": false,
            }),
        )?;
        Ok(browser)
    }

    fn send(&mut self, method: &str, params: Value, session: Option<&str>) -> Result<u64, String> {
        self.next_id += 1;
        let mut message = json!({ "id": self.next_id, "method": method, "params": params });
        if let Some(s) = session {
            message["sessionId"] = json!(s);
        }
        let mut bytes = message.to_string().into_bytes();
        bytes.push(0);
        self.to_browser
            .write_all(&bytes)
            .map_err(|e| format!("sending {method}: {e}"))?;
        Ok(self.next_id)
    }

    fn wait_reply(&mut self, id: u64, method: &str) -> Result<Value, String> {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let message = match self
                .from_browser
                .recv_timeout(left.min(Duration::from_millis(500)))
            {
                Ok(m) => m,
                Err(RecvTimeoutError::Timeout) => {
                    if let Ok(Some(status)) = self.child.try_wait() {
                        return Err(format!("chromium exited ({status}) during {method}"));
                    }
                    if Instant::now() >= deadline {
                        return Err(format!("no reply to {method} within 30 s"));
                    }
                    continue;
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(format!("chromium closed the pipe during {method}"))
                }
            };
            if message["id"].as_u64() == Some(id) {
                if let Some(error) = message.get("error") {
                    return Err(format!("{method}: {error}"));
                }
                return Ok(message["result"].clone());
            }
            self.note_event(&message);
            self.pending.push_back(message);
            if self.pending.len() > 1000 {
                self.pending.pop_front();
            }
        }
    }

    /// Records the errors a page reports: uncaught exceptions, console.error, and log
    /// entries of level error (e.g. Content-Security-Policy violations).
    fn note_event(&mut self, message: &Value) {
        let params = &message["params"];
        match message["method"].as_str() {
            Some("Runtime.exceptionThrown") => {
                let d = &params["exceptionDetails"];
                let text = d["exception"]["description"]
                    .as_str()
                    .or(d["text"].as_str());
                self.errors
                    .push(format!("exception: {}", text.unwrap_or("?")));
            }
            Some("Runtime.consoleAPICalled") if params["type"] == "error" => {
                let args: Vec<String> = params["args"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|a| {
                        a["value"]
                            .as_str()
                            .map(str::to_owned)
                            .or_else(|| a["description"].as_str().map(str::to_owned))
                            .unwrap_or_else(|| a["value"].to_string())
                    })
                    .collect();
                self.errors
                    .push(format!("console.error: {}", args.join(" ")));
            }
            Some("Log.entryAdded") if params["entry"]["level"] == "error" => {
                let text = params["entry"]["text"].as_str().unwrap_or("?");
                self.errors.push(format!("log: {text}"));
            }
            _ => {}
        }
    }

    fn call_browser(&mut self, method: &str, params: Value) -> Result<Value, String> {
        let id = self.send(method, params, None)?;
        self.wait_reply(id, method)
    }

    /// Sends a CDP command to the page and returns its result.
    pub fn call(&mut self, method: &str, params: Value) -> Result<Value, String> {
        let session = self.session.clone();
        let id = self.send(method, params, Some(&session))?;
        self.wait_reply(id, method)
    }

    /// Loads `url` in the page.
    pub fn navigate(&mut self, url: &str) -> Result<(), String> {
        let r = self.call("Page.navigate", json!({ "url": url }))?;
        match r.get("errorText") {
            Some(e) => Err(format!("navigating to {url}: {e}")),
            None => Ok(()),
        }
    }

    /// Evaluates a script expression in the page and returns its value (JSON).
    pub fn evaluate(&mut self, expression: &str) -> Result<Value, String> {
        let r = self.call(
            "Runtime.evaluate",
            json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }),
        )?;
        if let Some(e) = r.get("exceptionDetails") {
            return Err(format!("evaluating {expression}: {e}"));
        }
        Ok(r["result"]["value"].clone())
    }

    /// Waits until `document.body.dataset.settled` is `"true"`; returns data-status, the
    /// `#status` text and data-frame. Polls ten times a second.
    pub fn wait_settled(
        &mut self,
        budget: Duration,
    ) -> Result<(String, String, Option<u64>), String> {
        let deadline = Instant::now() + budget;
        let probe = "JSON.stringify(document.body ? { settled: document.body.dataset.settled, \
                     status: document.body.dataset.status, frame: document.body.dataset.frame, \
                     text: (document.getElementById('status') || {}).textContent, \
                     error: document.body.dataset.error } : {})";
        loop {
            let text = self.evaluate(probe)?;
            let v: Value = serde_json::from_str(text.as_str().unwrap_or("{}")).unwrap_or_default();
            if let Some(e) = v["error"].as_str() {
                return Err(format!(
                    "the page reported an error: {e}; {:?}",
                    self.errors
                ));
            }
            if v["settled"] == "true" {
                let frame = v["frame"].as_str().and_then(|f| f.parse().ok());
                let status = v["status"].as_str().unwrap_or_default().to_owned();
                let status_text = v["text"].as_str().unwrap_or_default().to_owned();
                return Ok((status, status_text, frame));
            }
            if Instant::now() >= deadline {
                return Err(format!(
                    "the page did not settle within {budget:?}: {v}; errors: {:?}",
                    self.errors
                ));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// A PNG of the viewport.
    pub fn screenshot(&mut self) -> Result<Vec<u8>, String> {
        let r = self.call("Page.captureScreenshot", json!({ "format": "png" }))?;
        decode_base64(r["data"].as_str().ok_or("no screenshot data")?)
    }

    /// A left click at viewport position (x, y), CSS pixels.
    pub fn click(&mut self, x: f64, y: f64) -> Result<(), String> {
        for kind in ["mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({ "type": kind, "x": x, "y": y, "button": "left", "buttons": 1, "clickCount": 1 }),
            )?;
        }
        Ok(())
    }

    /// Errors the page reported so far (exceptions, console errors, CSP violations).
    pub fn errors(&mut self) -> Vec<String> {
        while let Ok(m) = self.from_browser.try_recv() {
            self.note_event(&m);
        }
        self.errors.clone()
    }

    /// Closes the browser (and kills it if it does not exit within 5 s).
    pub fn close(mut self) {
        let _ = self.send("Browser.close", json!({}), None);
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn unique_dir() -> Result<PathBuf, String> {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!(
        "radiosity-headless-{}-{n}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    Ok(dir)
}

/// Standard base64 (RFC 4648 §4), padding optional.
fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    let value = |c: u8| -> Result<u32, String> {
        Ok(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return Err(format!("bad base64 byte {c}")),
        } as u32)
    };
    let bytes: Vec<u8> = text.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let mut acc = 0u32;
        for (i, &c) in chunk.iter().enumerate() {
            acc |= value(c)? << (18 - 6 * i);
        }
        let n = chunk.len().saturating_sub(1);
        out.extend_from_slice(&acc.to_be_bytes()[1..1 + n]);
    }
    Ok(out)
}

#[test]
fn base64_decodes_rfc_4648_vectors() {
    for (plain, coded) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(decode_base64(coded).unwrap(), plain.as_bytes());
    }
}
