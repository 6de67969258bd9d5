//! `vtsm ncc`.

/// Arguments of `vtsm ncc`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {}

/// Run the command; returns the exit code.
pub fn run(_args: &Args) -> crate::Result<u8> {
    Err(crate::Error::msg(
        "`vtsm ncc` is not available in this build",
    ))
}
