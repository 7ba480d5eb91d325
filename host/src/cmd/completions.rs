//! `cta completions SHELL` and `cta man`: shell completions and man pages, generated from the
//! same argument definitions as `--help`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, CommandFactory};
use clap_complete::Shell;

/// Print the completion script for a shell.
#[derive(Debug, Args)]
#[command(after_help = "EXAMPLES:
  cta completions bash > ~/.local/share/bash-completion/completions/cta
  cta completions zsh > ~/.zfunc/_cta        # with fpath+=(~/.zfunc) before compinit
  cta completions fish > ~/.config/fish/completions/cta.fish
  cta completions powershell >> $PROFILE")]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, powershell or elvish.
    #[arg(value_enum)]
    pub shell: Shell,
}

/// Write the man pages, one per command.
#[derive(Debug, Args)]
#[command(after_help = "EXAMPLE:
  cta man --out ~/.local/share/man/man1 && man cta-sweep")]
pub struct ManArgs {
    /// Folder for the pages: cta.1 and one cta-COMMAND.1 per command (created if missing).
    /// Without it, cta.1 is printed.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Run `cta completions`.
pub fn completions(a: &CompletionsArgs) -> Result<()> {
    write_completions(a.shell, &mut std::io::stdout())
}

/// The completion script for `shell` into `w`.
pub fn write_completions(shell: Shell, w: &mut dyn Write) -> Result<()> {
    let mut cmd = crate::Cli::command();
    clap_complete::generate(shell, &mut cmd, "cta", w);
    Ok(())
}

/// Run `cta man`.
pub fn man(a: &ManArgs) -> Result<()> {
    let cmd = crate::Cli::command();
    match &a.out {
        None => clap_mangen::Man::new(cmd)
            .render(&mut std::io::stdout())
            .context("cannot write the man page"),
        Some(dir) => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot write {}", dir.display()))?;
            clap_mangen::generate_to(cmd, dir)
                .with_context(|| format!("cannot write the man pages into {}", dir.display()))?;
            println!("man pages: {}", dir.display());
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn completions_know_every_command_and_its_options() {
        let mut out = Vec::new();
        write_completions(Shell::Bash, &mut out).unwrap();
        let s = String::from_utf8(out).unwrap();
        for word in [
            "sweep",
            "analyze",
            "calibrate",
            "--resume",
            "--sim-effect",
            "completions",
        ] {
            assert!(s.contains(word), "{word} missing from the bash completions");
        }
    }

    #[test]
    fn man_pages_one_per_command() {
        let dir = std::env::temp_dir().join(format!("cta-man-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        man(&ManArgs {
            out: Some(dir.clone()),
        })
        .unwrap();
        let page = std::fs::read_to_string(dir.join("cta-sweep.1")).unwrap();
        assert!(page.contains("resume"), "{page}");
        assert!(dir.join("cta.1").is_file() && dir.join("cta-sensor-pose.1").is_file());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `--version` names the commit the tool was built from.
    #[test]
    fn version_names_the_commit() {
        let v = crate::Cli::command().render_version();
        assert!(
            v.starts_with(&format!("cta {} (", env!("CARGO_PKG_VERSION"))),
            "{v}"
        );
        assert!(v.trim_end().ends_with(')') && !v.contains("()"), "{v}");
    }
}
