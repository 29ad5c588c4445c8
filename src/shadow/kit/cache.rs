//! Per-render caches: what several techniques, lights and add-ons derive
//! from the scene, computed once per render on first use (and never for a
//! render that does not need it).

use crate::geom::{EdgeAdjacency, SceneGeometry};
use crate::scene::Scene;
use crate::shadow::kit::groups::{semi_opaque_groups, Attenuation};
use crate::shadow::kit::rays::ShadowTracer;
use crate::shadow::kit::stsv::STriangles;
use crate::shadow::kit::volumes::caster_adjacency;
use std::borrow::Cow;
use std::sync::OnceLock;

/// Lazily filled, shared by every technique and light of one render.
pub struct ShadowCache<'a> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    casters: OnceLock<Cow<'a, EdgeAdjacency>>,
    s_triangles: OnceLock<STriangles>,
    semi_opaque: OnceLock<Vec<(Attenuation, EdgeAdjacency)>>,
    tracer: OnceLock<ShadowTracer<'a>>,
}

impl<'a> ShadowCache<'a> {
    /// An empty cache for `scene` and its concatenated `geometry`.
    pub fn new(scene: &'a Scene, geometry: &'a SceneGeometry) -> Self {
        ShadowCache {
            scene,
            geometry,
            casters: OnceLock::new(),
            s_triangles: OnceLock::new(),
            semi_opaque: OnceLock::new(),
            tracer: OnceLock::new(),
        }
    }

    /// The opaque shadow casters' edge adjacency (the scene's own when
    /// every triangle is one).
    pub fn casters(&self) -> &EdgeAdjacency {
        self.casters
            .get_or_init(|| caster_adjacency(self.scene, self.geometry))
    }

    /// The shadow-casting triangles with an opacity texture.
    pub fn s_triangles(&self) -> &STriangles {
        self.s_triangles
            .get_or_init(|| STriangles::collect(self.scene, self.geometry))
    }

    /// The semi-opaque casters, one group per distinct constant opacity.
    pub fn semi_opaque_groups(&self) -> &[(Attenuation, EdgeAdjacency)] {
        self.semi_opaque
            .get_or_init(|| semi_opaque_groups(self.scene, self.geometry))
    }

    /// The shadow-ray tracer (its BVHs built on first use).
    pub fn tracer(&self) -> &ShadowTracer<'a> {
        self.tracer
            .get_or_init(|| ShadowTracer::new(self.scene, self.geometry))
    }
}
