//! Ctrl-C (SIGINT) and SIGTERM: remove the temporary files of writes in progress, then exit
//! with the conventional status 130 (128 + SIGINT), so an interrupted job leaves no hidden
//! `.name.….tmp` file behind (the finished outputs are complete: they are renamed into place
//! only when whole, see `radiosity::io::atomic`).
//!
//! ctrlc allows one handler per process; anything else that must happen on an interrupt
//! belongs in this one.

/// Installs the handler (once; a failure to install is not fatal: the program just keeps
/// the default behaviour of dying on the signal).
pub fn remove_temporaries_on_signal() {
    let _ = ctrlc::set_handler(|| {
        radiosity::io::atomic::remove_temporaries();
        eprintln!("\ninterrupted");
        std::process::exit(130);
    });
}
