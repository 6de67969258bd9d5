//! `vtsm scene export`.

/// Arguments of `vtsm scene export`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {}

/// Run the command; returns the exit code.
pub fn run(_args: &Args) -> crate::Result<u8> {
    Err(crate::Error::msg(
        "`vtsm scene export` is not available in this build",
    ))
}
