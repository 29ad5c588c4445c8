//! What the shadow benches share: a shipped scene with its G-buffer at a
//! square size, ready to hand to a technique as a [`ShadowContext`].

use penumbra::internal::gbuffer::{gbuffer_pass, GBuffer};
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::raster::Framebuffer;
use penumbra::internal::render::{view_for, RenderOptions};
use penumbra::internal::scene::{load_scene, Scene};
use penumbra::internal::shadow::{ShadowCache, ShadowContext};
use penumbra::internal::view::View;
use std::path::Path;

/// A shipped scene's receivers, computed once per bench.
pub struct Prepared {
    pub scene: Scene,
    pub geometry: SceneGeometry,
    pub view: View,
    pub gbuffer: GBuffer,
    pub depth: Framebuffer,
}

impl Prepared {
    /// `scenes/<name>` at `size`² (panics: a bench of a shipped scene has
    /// no user input).
    pub fn new(name: &str, size: u32) -> Prepared {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let scene = load_scene(&path).expect("shipped scene loads");
        let options = RenderOptions {
            width: Some(size),
            height: Some(size),
            ..RenderOptions::default()
        };
        let view = view_for(&scene, &options).expect("view");
        let geometry = SceneGeometry::new(&scene);
        let (gbuffer, depth, _) = gbuffer_pass(&scene, &geometry, &view).expect("g-buffer");
        Prepared {
            scene,
            geometry,
            view,
            gbuffer,
            depth,
        }
    }

    /// The per-render cache (filled on first use, kept across iterations).
    pub fn cache(&self) -> ShadowCache<'_> {
        ShadowCache::new(&self.scene, &self.geometry)
    }

    /// The context a technique computes from.
    pub fn ctx<'a>(&'a self, cache: &'a ShadowCache<'a>) -> ShadowContext<'a> {
        ShadowContext {
            scene: &self.scene,
            geometry: &self.geometry,
            view: &self.view,
            gbuffer: &self.gbuffer,
            depth: &self.depth,
            cache,
            observer: &penumbra::internal::observe::Silent,
        }
    }
}
