//! Penumbra casting's options (a leaf: the technique list's options struct gathers them
//! without importing the technique).
use crate::shadow::kit::stsv::options::Filter;

/// Penumbra casting's command-line options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct PenumbraCastingOptions {
    /// Penumbra casting: distinct light-sample sets, assigned per receiver
    /// (§3.4). 0 (the default): the reference's own sets where the pattern
    /// has finitely many — `interleaved:n` gets its `n²` sets (while
    /// `n² × ⌈N/32⌉ ≤ 4096`), `correlated` and `grid` their one set — and
    /// the paper's 8 otherwise (per-pixel patterns such as `stratified`).
    /// With `interleaved:n` and `n²` sets, `correlated` or `grid`, every
    /// receiver gets the reference's samples of its pixel.
    #[arg(long, default_value_t = 0)]
    pub pc_sample_sets: u32,
    /// Penumbra casting: umbra bits and hierarchy rebuilds (§3.3 A).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_umbra_bits: bool,
    /// Penumbra casting: active plane sets (§3.3 B).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_active_planes: bool,
    /// Penumbra casting: lazy group and hard-shadow-volume construction
    /// (§3.3 C).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_lazy_volumes: bool,
    /// Penumbra casting: bit masks allocated on demand and freed at full
    /// umbra (§3.3 D).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_on_demand_masks: bool,
    /// Penumbra casting: coarse blocker sorting by area buckets, largest
    /// first (§3.3).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_sort_blockers: bool,
    /// Penumbra casting: point-in-volume tests through the SIMD facade
    /// (`false`: its scalar twin; same bits).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_simd: bool,
    /// Penumbra casting: skip the kernel for samples outside the cone from
    /// the receiver through the triangle (a conservative prefilter: same
    /// bits).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_cone_prefilter: bool,
    /// Penumbra casting: with the cone prefilter, the cone decides each
    /// remaining sample whose value is clear of the rounding allowance
    /// (the kernel's answer, proved) and the hard volumes are built only
    /// for the samples within it (same bits).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_cone_decides: bool,
    /// Penumbra casting: with `--pc-cone-decides`, the cone decides also
    /// for triangles whose plane splits the light, per sample by its side
    /// of the plane (same bits).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_cone_split: bool,
    /// Penumbra casting: skip the triangles of closed casters whose plane
    /// has the whole light strictly behind it (a segment crossing a closed
    /// surface crosses it both ways, so the light-facing crossings suffice).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub pc_cull_back_faces: bool,
    /// Penumbra casting: rebuild a chunk's hierarchy when more than this
    /// percentage of its receivers is in full umbra (0: never).
    #[arg(long, default_value_t = 25)]
    pub pc_rebuild_percent: u32,
    /// Penumbra casting: side in pixels of the square screen chunks whose
    /// receivers share a hierarchy (chunks run in parallel).
    #[arg(long, default_value_t = 256)]
    pub pc_chunk: u32,
    /// Penumbra casting: split a chunk in four (down to 64 px) while a
    /// probe of it (every fourth receiver in x and y, the first sixteenth
    /// of the triangles) counts more than this many triangles reaching its
    /// receivers' leaves (0: never), so that the chunk under a dense caster
    /// does not set the wall time alone.
    #[arg(long, default_value_t = 1 << 17)]
    pub pc_split_work: u64,
    /// Penumbra casting: most MiB of bit masks (receivers × samples bits)
    /// held at once; chunks are processed in waves that fit.
    #[arg(long, default_value_t = 1024)]
    pub pc_mask_budget_mib: u32,
    /// How S-triangles' opacity textures are read (the shared
    /// `--opacity-filter`, filled in by the registry's `build`).
    #[arg(skip)]
    pub opacity_filter: Filter,
}

impl Default for PenumbraCastingOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        PenumbraCastingOptions {
            pc_sample_sets: 0,
            pc_umbra_bits: true,
            pc_active_planes: true,
            pc_lazy_volumes: true,
            pc_on_demand_masks: true,
            pc_sort_blockers: true,
            pc_simd: true,
            pc_cone_prefilter: true,
            pc_cone_decides: true,
            pc_cone_split: true,
            pc_cull_back_faces: true,
            pc_rebuild_percent: 25,
            pc_chunk: 256,
            pc_split_work: 1 << 17,
            pc_mask_budget_mib: 1024,
            opacity_filter: Filter::Nearest,
        }
    }
}

impl PenumbraCastingOptions {
    /// Every optimisation off, scalar tests: the basic algorithm of Fig. 2.
    pub fn basic(self) -> Self {
        PenumbraCastingOptions {
            pc_umbra_bits: false,
            pc_active_planes: false,
            pc_lazy_volumes: false,
            pc_on_demand_masks: false,
            pc_sort_blockers: false,
            pc_simd: false,
            pc_cone_prefilter: false,
            pc_cone_decides: false,
            pc_cone_split: false,
            pc_cull_back_faces: false,
            pc_split_work: 0,
            ..self
        }
    }
}
