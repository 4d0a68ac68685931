//! `radiosity`: the command-line face of the radiosity engine. Thin on purpose: argument
//! parsing, progress bars and error reporting; all the work is in the library.

mod args;
mod cmd_compare;
mod cmd_formfactor;
mod cmd_progressive;
mod commands;
mod progress;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = args::Cli::parse();
    match commands::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
