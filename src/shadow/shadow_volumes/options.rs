//! Hard shadow volumes' options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

/// Hard shadow volumes' command-line options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::Args)]
pub struct ShadowVolumeOptions {
    /// Shadow volumes: count with z-pass instead of z-fail.
    #[arg(long)]
    pub zpass: bool,
}
