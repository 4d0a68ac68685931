//! An interrupted write leaves nothing behind: SIGINT or SIGTERM while `solve --save` is
//! writing its output makes the program exit non-zero with neither the output nor its hidden
//! temporary file (`.<name>.<pid>-<n>.tmp`) left in the directory (issue 12).
//!
//! Not timing-dependent: the test waits until the temporary file of the real write exists and
//! holds data (the empty probe that checks the output is writable before the solve does not
//! count), then signals. The write it interrupts is a solution of 100k elements (about
//! 40 MB of JSON, a second or more of writing), far longer than the few milliseconds the test
//! needs to see the file and signal.

#![cfg(unix)]

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The temporary files in `dir` that already hold data.
fn written_temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.metadata().is_ok_and(|m| m.len() > 0))
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

/// `closed_stderr`: the reading end of the program's stderr is closed first (its terminal or
/// the job that started it is gone), so that the handler's message cannot be written.
fn interrupt_the_write(signal: &str, closed_stderr: bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.solution.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["solve", "--solver", "progressive", "--max-shots", "1"])
        .args(["--elements", "100000", "--quiet", "--save"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run radiosity");
    if closed_stderr {
        drop(child.stderr.take());
    }
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        if !written_temporaries(dir.path()).is_empty() {
            break;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the solve ended ({status}) before its output was seen being written");
        }
        assert!(Instant::now() < deadline, "no output was written in 300 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    let sent = Command::new("kill")
        .args([format!("-{signal}"), child.id().to_string()])
        .status()
        .expect("run kill");
    assert!(sent.success(), "kill -{signal} failed");
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success(),
        "SIG{signal} during the write must not exit 0; stderr: {stderr}"
    );
    // The handler's exit, not death by the signal: it ran and cleaned up.
    assert_eq!(output.status.code(), Some(130), "stderr: {stderr}");
    let left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        left.is_empty(),
        "SIG{signal} during the write left {left:?} behind"
    );
}

#[test]
fn sigint_during_a_write_leaves_no_file_behind() {
    interrupt_the_write("INT", false);
}

#[test]
fn sigterm_during_a_write_leaves_no_file_behind() {
    interrupt_the_write("TERM", false);
}

/// Regression: the handler printed its message with `eprintln!`, which panics when stderr is
/// a closed pipe; the panic ended the handler's thread instead of the process, and the solve
/// ran on to the end, deaf to SIGTERM.
#[test]
fn sigterm_ends_the_program_when_nobody_reads_its_stderr() {
    interrupt_the_write("TERM", true);
}
