//! Shadow techniques, all behind one interface.
//!
//! A technique receives the resolved G-buffer, the scene depth buffer and
//! the scene, and returns for each light either a visibility coefficient
//! per pixel (the shading stage multiplies the unshadowed direct light by
//! it) or the shadowed direct radiance it integrated itself per light
//! sample. It may add AOV layers of its own and reports its passes' times.
//!
//! The layers, each importing only those below it:
//! - [`registry`]: the list of techniques, and queries over it;
//!   [`run`] and [`verify`] use a technique picked from it.
//! - one folder (or file) per technique: `none`, `reference`,
//!   `shadow_volumes`, `wedges`, `dcs`, `shadow_map`, `pcss`, `multi_map`,
//!   `adaptive_maps`, `soft_shadow_map`, `penumbra_casting`.
//! - [`technique`]: the interface and the vocabulary techniques describe
//!   themselves with; [`kit`]: building blocks several techniques share.
//! - [`options`]: every technique's options gathered from the leaf
//!   `options.rs` files.

#[forbid(unsafe_code)]
pub mod adaptive_maps;
pub mod dcs;
pub mod kit;
#[forbid(unsafe_code)]
pub mod multi_map;
#[forbid(unsafe_code)]
pub mod none;
#[forbid(unsafe_code)]
pub mod options;
#[forbid(unsafe_code)]
pub mod pcss;
pub mod penumbra_casting;
#[forbid(unsafe_code)]
pub mod reference;
#[forbid(unsafe_code)]
pub mod registry;
#[forbid(unsafe_code)]
pub mod run;
#[forbid(unsafe_code)]
pub mod shadow_map;
#[forbid(unsafe_code)]
pub mod shadow_volumes;
#[forbid(unsafe_code)]
pub mod soft_shadow_map;
#[forbid(unsafe_code)]
pub mod technique;
#[forbid(unsafe_code)]
pub mod verify;
#[forbid(unsafe_code)]
pub mod wedges;

pub use kit::cache::ShadowCache;
pub use options::{OptionGroup, TechniqueOptions};
pub use registry::Technique;
pub use run::run_technique;
pub use technique::{
    BufferNote, LightTerm, PassTiming, ShadowContext, ShadowOutput, ShadowTechnique, Warning,
};
