//! DCS's options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

use crate::shadow::kit::groups::TransmittanceMode;

/// What the counters are turned into.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum DcsMode {
    /// A visibility coefficient modulating the unshadowed direct light
    /// (eq. 4.1): an approximation of the image.
    Vcoef,
    /// The direct light integrated over the samples, each weighted by its
    /// binary visibility (eq. 4.6): the exact image, the default.
    #[default]
    Direct,
}

impl DcsMode {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            DcsMode::Vcoef => "vcoef",
            DcsMode::Direct => "direct",
        }
    }
}

/// Depth complexity sampling's command-line options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct DcsOptions {
    /// Depth complexity sampling: wedges on the silhouettes from the whole
    /// light (`light`, exact, the default) or from the light's centre
    /// (`centre`, faster, misses edges that are silhouettes only from
    /// other points of the light).
    #[arg(long, value_enum, default_value_t = SilhouetteMode::WholeLight)]
    pub silhouettes: SilhouetteMode,
    /// Depth complexity sampling: `direct` (integrate the light per
    /// sample, eq. 4.6: the exact image, the default) or `vcoef` (modulate
    /// the unshadowed light by the visibility coefficient, eq. 4.1: an
    /// approximation, biased where shadow and shading vary together).
    #[arg(long = "dcs-mode", value_enum, default_value_t = DcsMode::Direct)]
    pub mode: DcsMode,
    /// Depth complexity sampling: semi-opaque casters' transmittance,
    /// `exact` (the product of `1 − opacity` per layer) or `summed` (the
    /// thesis's summed-opacity approximation).
    #[arg(long, value_enum, default_value_t = TransmittanceMode::Exact)]
    pub transmittance: TransmittanceMode,
    /// Depth complexity sampling: covered samples by the exact per-sample
    /// test (`exact`) or the thesis's precomputed bit fields (`bitfield`,
    /// approximate; correlated or interleaved patterns on rect lights).
    #[arg(long, value_enum, default_value_t = CoverageTest::Exact)]
    pub coverage: CoverageTest,
    /// Depth complexity sampling: where counting edges would cost more
    /// than tracing the same samples' shadow rays, trace them (`auto`, the
    /// default: both are exact, the choice follows a cost estimate made
    /// from counts alone, so it is the same for any thread count), or
    /// always count (`never`: the algorithm alone, for studying it).
    #[arg(long = "dcs-rays", value_enum, default_value_t = RayChoice::Auto)]
    pub rays: RayChoice,
}

/// Whether DCS may trace shadow rays where they cost less than counting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum RayChoice {
    /// Per light, whichever the cost estimate says is cheaper.
    #[default]
    Auto,
    /// Always count edges.
    Never,
    /// Trace every receiver's shadow rays wherever rays are an option (the
    /// traced path alone, for studying it and the cost choice).
    Always,
}

impl RayChoice {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            RayChoice::Auto => "auto",
            RayChoice::Never => "never",
            RayChoice::Always => "always",
        }
    }
}

impl Default for DcsOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        DcsOptions {
            silhouettes: SilhouetteMode::WholeLight,
            mode: DcsMode::Direct,
            transmittance: TransmittanceMode::Exact,
            coverage: CoverageTest::Exact,
            rays: RayChoice::Auto,
        }
    }
}

/// How the samples an edge covers are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum CoverageTest {
    /// The exact per-sample test, SIMD over samples.
    #[default]
    Exact,
    /// The thesis's precomputed bit fields (Fig. 4.9), approximate; only
    /// for sample sets shared by many pixels on rect lights.
    #[value(name = "bitfield")]
    BitField,
}

impl CoverageTest {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            CoverageTest::Exact => "exact",
            CoverageTest::BitField => "bitfield",
        }
    }
}

/// Which edges get wedges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum SilhouetteMode {
    /// Silhouettes from the light's centre (the thesis's default; fast,
    /// but misses edges that are silhouettes only from other parts of the
    /// light).
    #[value(alias = "center")]
    Centre,
    /// Edges that are silhouettes from some point of the light (§4.1.4):
    /// every edge that can change `D` for some receiver. Exact; our
    /// default.
    #[default]
    #[value(name = "light", alias = "whole-light")]
    WholeLight,
}

impl SilhouetteMode {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            SilhouetteMode::Centre => "centre",
            SilhouetteMode::WholeLight => "light",
        }
    }
}
