//! `radiosity`: the command-line face of the radiosity engine. Thin on purpose: argument
//! parsing, progress bars and error reporting; all the work is in the library.

/// `eprintln!` that does not panic when standard error is gone (`radiosity solve 2>&1 | head
/// -1`: a closed pipe): the message is dropped and the work goes on, its files written
/// (`eprintln!` panicked there, before the report was written). Defined before the modules
/// so that they all see it.
macro_rules! stderr_line {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod args;
mod cmd_compare;
mod cmd_falsecolour;
mod cmd_formfactor;
mod cmd_measure;
mod cmd_progressive;
mod cmd_shell;
mod cmd_view;
mod commands;
mod interrupt;
mod progress;
mod view;

use clap::error::ErrorKind;
use clap::Parser;
use std::process::ExitCode;

/// Writes `text` to standard output. A reader that has gone away (`radiosity solve | head
/// -1`: a closed pipe) is not an error: the work goes on and its files are written, only
/// the rest of the text is dropped (`println!` panicked there). Any other failure to write
/// is returned, for the command to fail with it.
pub(crate) fn write_stdout(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(anyhow::Error::new(e).context("writing to standard output"))
        }
        _ => Ok(()),
    }
}

fn main() -> ExitCode {
    let cli = match args::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout with success; every usage error is exit 1,
            // like every other error.
            let code = match e.kind() {
                ErrorKind::DisplayHelp
                | ErrorKind::DisplayVersion
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => ExitCode::SUCCESS,
                _ => ExitCode::FAILURE,
            };
            let _ = e.print();
            return code;
        }
    };
    interrupt::remove_temporaries_on_signal();
    if let Some(n) = cli.threads {
        if !(1..=MAX_THREADS).contains(&n) {
            stderr_line!(
                "error: --threads must be a whole number from 1 to {MAX_THREADS}, got {n}"
            );
            return ExitCode::FAILURE;
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            stderr_line!("error: --threads: {e}");
            return ExitCode::FAILURE;
        }
    }
    match commands::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            stderr_line!("error: {}", message(&e));
            ExitCode::FAILURE
        }
    }
}

/// The most worker threads `--threads` accepts.
const MAX_THREADS: usize = 1024;

/// The error and its causes joined by ": ", each said once: library errors that already
/// quote their cause in their own message (`file: line 3: polygon has 2 distinct
/// vertices…`) also return it as their source, and printing both would repeat it.
fn message(error: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}
