//! PCSS's options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

use crate::error::{Error, Result};

/// Most taps of either PCSS stage.
pub const MAX_PCSS_SAMPLES: u32 = 4096;

/// The tap pattern of PCSS's blocker search and filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PcssKernel {
    /// A Poisson disk, rotated per pixel (NVIDIA's code, ours rotated).
    #[default]
    Poisson,
    /// A regular `⌈√N⌉²` grid over the light's whole rectangle, not
    /// rotated: dense and deterministic (a box filter).
    Box,
}

/// PCSS's command-line options (the map itself takes the shadow-map
/// options `--map-size`, `--depth-bias`, `--slope-bias`, `--normal-offset`).
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct PcssOptions {
    /// PCSS: taps of the blocker search (the paper's figure uses 64).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=MAX_PCSS_SAMPLES as i64))]
    pub pcss_blocker_samples: u32,
    /// PCSS: taps of the percentage-closer filter (the paper's figure uses 64).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=MAX_PCSS_SAMPLES as i64))]
    pub pcss_filter_samples: u32,
    /// PCSS: tap pattern, `poisson` (rotated per pixel) or `box` (a regular
    /// grid over the light's rectangle).
    #[arg(long, value_enum, default_value_t = PcssKernel::Poisson)]
    pub pcss_kernel: PcssKernel,
    /// PCSS: compare every tap with the receiver's own depth instead of
    /// its plane's depth at the tap (no receiver-plane depth bias).
    #[arg(long)]
    pub pcss_flat_receiver: bool,
}

impl Default for PcssOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        PcssOptions {
            pcss_blocker_samples: 16,
            pcss_filter_samples: 16,
            pcss_kernel: PcssKernel::Poisson,
            pcss_flat_receiver: false,
        }
    }
}

impl PcssOptions {
    /// Refuses sample counts outside `1..=MAX_PCSS_SAMPLES`, naming the
    /// option.
    pub fn validate(&self) -> Result<()> {
        for (name, n) in [
            ("--pcss-blocker-samples", self.pcss_blocker_samples),
            ("--pcss-filter-samples", self.pcss_filter_samples),
        ] {
            if !(1..=MAX_PCSS_SAMPLES).contains(&n) {
                return Err(Error::param(
                    name,
                    format!("{n} is outside 1..={MAX_PCSS_SAMPLES}"),
                ));
            }
        }
        Ok(())
    }
}
