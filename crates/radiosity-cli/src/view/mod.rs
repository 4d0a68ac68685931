//! `radiosity view`: a live browser viewer of the solution while the solver runs.
//!
//! A small HTTP/1.1 server on 127.0.0.1 ([`Server`]) serves one page with three.js, all
//! embedded in the binary ([`assets`]), and the solver's latest mesh, frame and progress from
//! a shared [`ViewState`]. The page listens to server-sent events and fetches each new frame.
//!
//! Typical use from the command:
//!
//! ```ignore
//! let state = Arc::new(ViewState::new());
//! let server = Server::bind(state.clone(), ServerConfig { port, ..Default::default() })?;
//! println!("{}", server.url());
//! let running = server.spawn()?;
//! shutdown_on_signal(running.shutdown_handle())?;
//! // solver thread: state.set_mesh(..), state.set_frame(..), state.set_progress(..),
//! // then state.finish(Outcome::Converged); the page keeps serving until Ctrl-C.
//! running.join()?;
//! ```
//!
//! See also `protocol.rs` for the data and the wire format, `build.rs` for how the library's
//! display mesh becomes the viewer's mesh and frames, `server.rs` for the endpoints and
//! limits, `assets/view/` for the page, and `cmd_view.rs` for the command.

pub mod assets;
pub mod build;
pub mod http;
pub mod protocol;
pub mod server;

#[cfg(test)]
mod browser_tests;
#[cfg(test)]
mod test_scene;
#[cfg(test)]
mod tests;

pub use protocol::{Outcome, ViewCamera, ViewError, ViewFrame, ViewMesh, ViewProgress, ViewState};
pub use server::{Server, ServerConfig, ShutdownHandle};

use std::process::{Command, Stdio};

/// Installs the process's Ctrl-C (SIGINT) and SIGTERM handler: the first signal shuts the
/// server down (and any solver loop that polls [`ShutdownHandle::is_shutdown`] stops); a
/// second one exits at once with status 130.
///
/// The process's one signal handler is `crate::interrupt`'s; this hooks into it. Call it
/// once, from the command, not from tests.
pub fn shutdown_on_signal(handle: ShutdownHandle) -> Result<(), ViewError> {
    crate::interrupt::on_interrupt(move || {
        if handle.is_shutdown() {
            return false;
        }
        handle.shutdown();
        true
    });
    Ok(())
}

/// Opens `url` in the desktop's browser (`xdg-open`, macOS `open`, Windows `start`) without
/// waiting for it; the opener's output is discarded.
pub fn open_in_browser(url: &str) -> Result<(), ViewError> {
    let mut command = if cfg!(target_os = "macos") {
        Command::new("open")
    } else if cfg!(windows) {
        let mut c = Command::new("cmd");
        c.args(["/C", "start", ""]);
        c
    } else {
        Command::new("xdg-open")
    };
    let mut child = command
        .arg(url)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|source| ViewError::Browser {
            url: url.to_owned(),
            source,
        })?;
    // Reap the opener when it exits, so that it leaves no zombie behind.
    std::thread::spawn(move || child.wait());
    Ok(())
}
