//! The DCS technique's settings and its per-light report: what its passes
//! read and fill, in a leaf so that the passes need not import the module
//! that runs them.

use super::options::{CoverageTest, DcsMode, RayChoice, SilhouetteMode};
use crate::sampling::SamplePattern;
use crate::shadow::kit::groups::TransmittanceMode;
use crate::shadow::kit::stsv::options::Filter;

/// The depth-complexity-sampling technique.
#[derive(Debug, Clone, Copy)]
pub struct DepthComplexitySampling {
    /// Light samples per receiver and light (any `N ≥ 1`).
    pub samples: u32,
    /// Seed of the light samples (the reference's, for the same pixel).
    pub seed: u64,
    /// Which edges get wedges.
    pub silhouettes: SilhouetteMode,
    /// Vcoef or direct-lighting output.
    pub mode: DcsMode,
    /// How samples are placed on the light (shared with the reference).
    pub pattern: SamplePattern,
    /// How semi-opaque casters' layer counts become transmittance.
    pub transmittance: TransmittanceMode,
    /// How covered samples are found.
    pub coverage: CoverageTest,
    /// Look-up of S-triangles' opacity textures.
    pub opacity_filter: Filter,
    /// Whether shadow rays may replace counting where they cost less.
    pub rays: RayChoice,
}

/// Per-light buffers for `--explain`.
#[derive(Debug, Clone, Default)]
pub struct DcsLightReport {
    /// Candidate edges (wedges requested), over all caster groups.
    pub candidate_edges: usize,
    /// Semi-opaque caster groups (one per distinct opacity).
    pub semi_opaque_groups: usize,
    /// Edges with no bounded wedge (applied to every receiver).
    pub unbounded_edges: usize,
    /// Half-wedge triangles drawn.
    pub wedge_triangles: usize,
    /// (pixel, edge) pairs recorded.
    pub pairs: usize,
    /// (pixel, edge) pairs from edges without a bounded wedge.
    pub unbounded_pairs: usize,
    /// Receivers that needed per-sample counters.
    pub sampled_pixels: usize,
    /// Receivers whose start count was recounted by a ray because a
    /// quad's plane passes between the raster's receiver and the
    /// shadow-ray origin.
    pub quad_recounts: usize,
    /// Receivers traced by shadow rays instead of counted (the cost
    /// choice).
    pub traced_pixels: usize,
    /// The light's plan: counted, or every receiver traced.
    pub plan: Option<super::plan::LightPlan>,
    /// Bytes of the unbounded edges' regions, their clusters' and the
    /// halves' edge ids.
    pub region_bytes: u64,
    /// Bytes of the start-count tie recount (group table, face tree).
    pub tie_bytes: u64,
    /// Whether the tie recount built its face tree.
    pub tie_tree: bool,
}
