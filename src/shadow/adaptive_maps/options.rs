//! Adaptive light-source sampling's options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

/// Deepest `--max-depth` accepted: 65 × 65 = 4225 points.
pub const MAX_DEPTH: u32 = 6;

/// Adaptive maps' command-line options (map size, PCF and biases are the
/// shadow maps').
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct AdaptiveMapsOptions {
    /// Adaptive maps: a quad splits when more receivers than this fail the
    /// banding test (0, the paper's, splits on one).
    #[arg(long, default_value_t = 0)]
    pub adaptive_threshold: u64,
    /// Adaptive maps: deepest light subdivision (4: at most 17 × 17 = 289
    /// maps).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(0..=MAX_DEPTH as i64))]
    pub max_depth: u32,
    /// Adaptive maps: size of the comparison target as a fraction of the
    /// image's (§3.3.2: smaller → fewer maps, banding).
    #[arg(long, default_value_t = 1.0)]
    pub comparison_scale: f64,
    /// Adaptive maps: quads shallower than this get a centre probe when
    /// their corners alone do not split them (the fix for occluders whose
    /// shadows fall between all four corner maps); 0 turns it off (the
    /// paper).
    #[arg(long, default_value_t = 2)]
    pub adaptive_centre_depth: u32,
    /// Adaptive maps: split every quad down to --max-depth (the regular
    /// (2^D+1)² grid through the adaptive machinery; for tests).
    #[arg(long)]
    pub adaptive_split_all: bool,
    /// Adaptive maps: low end of the bias band of the banding test, a normal
    /// offset in texels without slope bias (capped at the run's own). A
    /// receiver whose hard test from one of the quad's corners differs
    /// between the band's ends is acne or light leak, not banding: the test
    /// leaves it out.
    #[arg(long, default_value_t = 0.5)]
    pub adaptive_band_low: f64,
    /// Adaptive maps: high end of the bias band, normal offset and slope
    /// bias in texels (at least the run's own); 0 turns the band off (the
    /// paper's test).
    #[arg(long, default_value_t = 4.0)]
    pub adaptive_band_high: f64,
}

impl Default for AdaptiveMapsOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        AdaptiveMapsOptions {
            adaptive_threshold: 0,
            max_depth: 4,
            comparison_scale: 1.0,
            adaptive_centre_depth: 2,
            adaptive_split_all: false,
            adaptive_band_low: 0.5,
            adaptive_band_high: 4.0,
        }
    }
}
