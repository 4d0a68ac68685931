//! `radiosity completions SHELL` and `radiosity man`: shell completions and manual pages,
//! generated from the same argument definitions as `--help` (clap_complete, clap_mangen), so
//! they cannot drift from the real flags.

use crate::args::Cli;
use anyhow::{Context, Result};
use clap::{Args, CommandFactory};
use std::io::Write;
use std::path::PathBuf;

/// `radiosity completions`.
#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, elvish or powershell. Install, e.g. for bash:
    /// `radiosity completions bash > ~/.local/share/bash-completion/completions/radiosity`.
    pub shell: clap_complete::Shell,
}

/// `radiosity man`.
#[derive(Debug, Args)]
pub struct ManArgs {
    /// Write one page per command (radiosity.1, radiosity-render.1, …) into this directory
    /// (created if missing) instead of printing radiosity.1 to standard output.
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
}

/// Prints the completion script for a shell.
pub fn completions(args: CompletionsArgs) -> Result<()> {
    let mut command = Cli::command();
    let mut out = std::io::stdout().lock();
    clap_complete::generate(args.shell, &mut command, "radiosity", &mut out);
    out.flush()?;
    Ok(())
}

/// Prints the manual page, or writes one per command into a directory.
pub fn man(args: ManArgs) -> Result<()> {
    let command = Cli::command();
    let Some(dir) = args.output else {
        let mut out = std::io::stdout().lock();
        clap_mangen::Man::new(command).render(&mut out)?;
        out.flush()?;
        return Ok(());
    };
    crate::cmd_progressive::prepare_output_dir(&dir)?;
    let mut pages = vec![("radiosity".to_owned(), command.clone())];
    for sub in command.get_subcommands() {
        pages.push((format!("radiosity-{}", sub.get_name()), sub.clone()));
    }
    for (name, page) in pages {
        let path = dir.join(format!("{name}.1"));
        radiosity::io::atomic::write_atomically(&path, |w| {
            clap_mangen::Man::new(page)
                .title(name.clone())
                .render(&mut *w)
        })
        .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
