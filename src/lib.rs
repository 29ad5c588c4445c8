//! penumbra: a pure-software renderer for physically based soft shadows.
//!
//! The library is the items at this crate's root: a [`Scene`] (from a file
//! with [`load_scene`], from TOML text with [`scene_from_toml`], or
//! described in code with a [`SceneBuilder`]), the
//! [`RenderOptions`] of one render (plain defaults, one [`validate`] for
//! every range check, which the command line calls too), and [`render`],
//! which returns a [`Render`]: radiance, the requested AOV layers and
//! each light's term as typed buffers, the time of every pass and the
//! `--explain` report as data. [`render_with`] reports progress to an
//! [`Observer`] and stops when it says so ([`Cancel`]). [`techniques`]
//! lists the shadow techniques and what each can honour; [`compare`]
//! measures techniques against the ray-traced reference and returns the
//! rows of `penumbra compare`'s results.csv as [`Record`]s.
//!
//! ```
//! use penumbra::{render, scene_from_toml, RenderOptions};
//!
//! let scene = scene_from_toml(
//!     r#"
//!     [camera]
//!     eye = [0.0, 5.0, 6.0]
//!     target = [0.0, 0.0, 0.0]
//!     fov_y = 45
//!     width = 32
//!     height = 24
//!     [[light]]
//!     type = "rect"
//!     center = [0.0, 4.0, 0.0]
//!     u = [0.5, 0.0, 0.0]
//!     v = [0.0, 0.0, 0.5]
//!     radiance = 10
//!     [[object]]
//!     name = "ground"
//!     shape = "quad"
//!     size = [6.0, 6.0]
//!     [[object]]
//!     name = "occluder"
//!     shape = "quad"
//!     size = [1.0, 1.0]
//!     translate = [0.0, 1.0, 0.0]
//!     "#,
//!     std::path::Path::new("."),
//! )?;
//! let options = RenderOptions {
//!     samples: 16,
//!     ..RenderOptions::default() // dcs: the exact image
//! };
//! let image = render(&scene, &options)?;
//! assert_eq!(image.radiance.len(), 32 * 24);
//! // The occluder's shadow: some pixels see less of the light.
//! let vcoef = image.lights[0].vcoef();
//! assert!(vcoef.iter().any(|&v| v < 1.0) && vcoef.iter().any(|&v| v == 1.0));
//! # Ok::<(), penumbra::Error>(())
//! ```
//!
//! The pipeline's modules (scene loading → geometry → the raster pipeline
//! → the G-buffer → shadow techniques → shading → output and reports) are
//! not part of this interface; the command line, the benches and the tests
//! reach them through `penumbra::internal`, which may change at any time.
//! docs/library.md and docs/architecture.md describe both.
//!
//! [`validate`]: RenderOptions::validate

// `!(x > 0.0)` is how this crate rejects NaN together with the failing
// range: the negation is the point, not an accident.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

/// The pipeline's modules: not the library's interface (see the module).
#[doc(hidden)]
pub mod internal;

pub(crate) use internal::{
    allocator, cluster, compare, error, gbuffer, geom, observe, output, raster, render, report,
    sampling, scene, shade, shadow, simd, view,
};

pub use compare::{compare, compare_with, CompareOptions, Record, CSV_COLUMNS};
pub use error::{Error, Result};
pub use observe::{Cancel, Observer, Silent};
pub use output::Layer;
pub use render::{
    render, render_with, Aov, Convergence, Explain, Render, RenderOptions, SetPoint, SetStatus,
    StopReason, StopRule, Technique,
};
pub use sampling::SamplePattern;
pub use scene::{
    load_scene, scene_from_toml, CameraDesc, Geometry, LightDesc, MaterialDesc, MeshData,
    ObjectDesc, Scene, SceneBuilder, BUILT_SCENE,
};
pub use shadow::registry::TechniqueData;
pub use shadow::{BufferNote, LightTerm, PassTiming, TechniqueOptions, Warning};

/// Every shadow technique, in the registry's order, with what it can
/// honour and what it costs (`penumbra techniques --json` prints the same).
pub fn techniques() -> Vec<TechniqueData> {
    shadow::registry::technique_data()
}
