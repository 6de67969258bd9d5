//! `vtsm budget`.

/// Arguments of `vtsm budget`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {}

/// Run the command; returns the exit code.
pub fn run(_args: &Args) -> crate::Result<u8> {
    Err(crate::Error::msg(
        "`vtsm budget` is not available in this build",
    ))
}
