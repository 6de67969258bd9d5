//! `vtsm relocalize`.

/// Arguments of `vtsm relocalize`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {}

/// Run the command; returns the exit code.
pub fn run(_args: &Args) -> crate::Result<u8> {
    Err(crate::Error::msg(
        "`vtsm relocalize` is not available in this build",
    ))
}
