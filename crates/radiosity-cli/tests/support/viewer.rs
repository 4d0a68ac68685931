//! A `radiosity view` process for tests: started with `--port 0`, its URL read from the first
//! line of its stdout, stopped with SIGINT (as Ctrl-C would) or killed when dropped.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// A running `radiosity view`.
pub struct Viewer {
    child: Child,
    /// `http://127.0.0.1:PORT/`, as printed.
    pub url: String,
    /// The port it serves on.
    pub port: u16,
    stderr: mpsc::Receiver<String>,
}

/// Runs the binary with `args` (after `view --port 0`) and waits (at most `timeout`) for the
/// URL on its stdout.
pub fn start(args: &[&str], timeout: Duration) -> Viewer {
    let mut child = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["view", "--port", "0"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting radiosity view");
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = BufReader::new(stdout).read_line(&mut line);
        let _ = tx.send(line);
    });
    let mut stderr = child.stderr.take().unwrap();
    let (etx, erx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        let _ = etx.send(text);
    });
    let line = match rx.recv_timeout(timeout) {
        Ok(line) => line,
        Err(_) => {
            let _ = child.kill();
            panic!("radiosity view printed no URL within {timeout:?}");
        }
    };
    let url = line.trim().to_owned();
    let port = url
        .strip_prefix("http://127.0.0.1:")
        .and_then(|rest| rest.strip_suffix('/'))
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("not a viewer URL on stdout: {line:?}"));
    Viewer {
        child,
        url,
        port,
        stderr: erx,
    }
}

impl Viewer {
    /// Sends SIGINT (Ctrl-C) and waits at most `timeout` for the process to exit; returns
    /// its exit status, the time it took and its stderr.
    pub fn interrupt(mut self, timeout: Duration) -> (ExitStatus, Duration, String) {
        let sent = Instant::now();
        let ok = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status()
            .expect("running kill")
            .success();
        assert!(ok, "kill -INT failed");
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let took = sent.elapsed();
                let stderr = self
                    .stderr
                    .recv_timeout(Duration::from_secs(5))
                    .unwrap_or_default();
                return (status, took, stderr);
            }
            assert!(
                sent.elapsed() < timeout,
                "radiosity view did not exit within {timeout:?} of SIGINT"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Whether the process is still running.
    pub fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Waits for the process to exit on its own; returns its status and stderr.
    pub fn wait(mut self, timeout: Duration) -> (ExitStatus, String) {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let stderr = self
                    .stderr
                    .recv_timeout(Duration::from_secs(5))
                    .unwrap_or_default();
                return (status, stderr);
            }
            assert!(
                start.elapsed() < timeout,
                "radiosity view did not exit within {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
