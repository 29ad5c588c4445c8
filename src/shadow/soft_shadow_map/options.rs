//! Soft shadow maps' options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

/// Precision the micro-patches' occlusion is summed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Accumulate {
    /// f32 (what fp32 blending would have given; the default).
    #[default]
    F32,
    /// IEEE half precision, rounded once per blend as 2006 fp16 blending
    /// did (appendix A): fails where eq. 4 says.
    F16,
    /// f16 in `⌊√M⌋` batches of patches, each batch summed on its own and
    /// added to an intermediate sum (appendix A's workaround).
    F16Batched,
}

/// How a receiver reads the SSM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Lookup {
    /// The texel the receiver projects into.
    Nearest,
    /// The four nearest texels, weighted bilinearly.
    #[default]
    Bilinear,
}

/// Soft shadow maps' own options (the map size and the depth biases are
/// the shadow maps' `--map-size`, `--depth-bias`, `--slope-bias`,
/// `--normal-offset`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct SsmOptions {
    /// Soft shadow maps: 1 = the front (nearest) faces' patches; 2 = also
    /// the nearest back faces', in a second SSM, merged by max (§3.5).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub ssm_passes: u8,
    /// Soft shadow maps: in one pass, add a patch at the back faces' depth
    /// under each outline texel of the occluder map (our reading of
    /// Fig. 11b "one pass with bottom patches").
    #[arg(long)]
    pub ssm_bottom_patches: bool,
    /// Soft shadow maps: accumulation precision, f32 | f16 | f16-batched.
    #[arg(long, value_enum, default_value_t = Accumulate::F32)]
    pub ssm_accumulate: Accumulate,
    /// Soft shadow maps: look-up of the SSM per receiver, nearest | bilinear.
    #[arg(long, value_enum, default_value_t = Lookup::Bilinear)]
    pub ssm_lookup: Lookup,
}

impl Default for SsmOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        SsmOptions {
            ssm_passes: 1,
            ssm_bottom_patches: false,
            ssm_accumulate: Accumulate::F32,
            ssm_lookup: Lookup::Bilinear,
        }
    }
}
