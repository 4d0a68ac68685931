//! Ctrl-C (SIGINT) and SIGTERM: remove the temporary files of writes in progress, then exit
//! with the conventional status 130 (128 + SIGINT), so an interrupted job leaves no hidden
//! `.name.….tmp` file behind (the finished outputs are complete: they are renamed into place
//! only when whole, see `radiosity::io::atomic`).
//!
//! ctrlc allows one handler per process; anything else that must happen on an interrupt
//! belongs in this one.

use std::io::Write;
use std::sync::Mutex;

/// What a command asks to happen on an interrupt instead of exiting: returns true when it has
/// taken the signal (the command winds down by itself), false to exit as usual.
type Hook = Box<dyn Fn() -> bool + Send>;

static HOOK: Mutex<Option<Hook>> = Mutex::new(None);

/// Installs the handler (once; a failure to install is not fatal: the program just keeps
/// the default behaviour of dying on the signal).
pub fn remove_temporaries_on_signal() {
    let _ = ctrlc::set_handler(|| {
        let taken = HOOK
            .lock()
            .ok()
            .and_then(|hook| hook.as_ref().map(|f| f()))
            .unwrap_or(false);
        if taken {
            return;
        }
        radiosity::io::atomic::remove_temporaries();
        // Not eprintln!: it panics when stderr is a closed pipe (the terminal or the job that
        // started us is gone), and a panic here ended this thread instead of the process,
        // which then ran on, ignoring SIGTERM.
        let _ = writeln!(std::io::stderr(), "\ninterrupted");
        std::process::exit(130);
    });
}

/// Lets a long-running command (the live viewer) take the interrupt itself: `hook` runs on
/// each Ctrl-C or SIGTERM and returns whether it took it; when it does not, the handler
/// cleans up and exits with status 130.
pub fn on_interrupt(hook: impl Fn() -> bool + Send + 'static) {
    if let Ok(mut slot) = HOOK.lock() {
        *slot = Some(Box::new(hook));
    }
}
