//! Soft textured shadow volumes (thesis ch. 5): the shadows of triangles
//! whose opacity varies over their surface (S-triangles: a fence, a leaf,
//! a billboard with an opacity texture).
//!
//! This module is the technique's core, for the shadow techniques to call:
//!
//! 1. [`STriangles::collect`]: every shadow-casting triangle whose material
//!    has an opacity texture (`map_d`), with what its look-ups need.
//! 2. [`volume`]: per light, the STSV of each S-triangle (§5.1.2), a closed
//!    convex polyhedron holding every point that some light point sees
//!    through the triangle, one per side of the triangle's plane the light
//!    reaches (the two-sided case), and the exact planes of the
//!    point-in-STSV test (§5.1.3).
//! 3. [`membership()`]: all volumes rasterized with z-fail counting against
//!    the scene depth; per tile, the `(pixel, S-triangle)` pairs whose
//!    receiver is inside, after the exact plane test on the shadow-ray
//!    origin.
//! 4. [`lookup`]: per receiver and S-triangle, `J = W·M'` (eqs. 5.7–5.9)
//!    and, per light sample, the opacity `d × map_d(uv)` where the segment
//!    from the receiver's shadow-ray origin to the sample crosses the
//!    triangle, 0 where it misses (eq. 5.10); nearest (the reference's
//!    rule) or bilinear, eight samples at a time.
//! 5. [`occlusion`]: for the Vcoef techniques (penumbra wedges, wedge
//!    blending, §5.2.1), each receiver's occluded fraction
//!    `1 − mean_k Π (1 − α)`, added to their V-buffer. Depth complexity
//!    sampling (§5.2.2) uses 3 and 4 directly in its counter pass.
//!
//! `docs/algorithms/stsv.md` says what the thesis does, what we do and
//! where we differ.

pub mod addon;
pub mod lookup;
pub mod membership;
pub mod occlusion;
pub mod options;
pub mod volume;

pub use addon::subtract_occlusion;
pub use lookup::{bilinear_scalar, SamplePositions, SampleProjector};
pub use membership::{membership, raster_mesh, StsvMembership};
pub use occlusion::{occlusion_note, stsv_occlusion, StsvOcclusion, StsvSampling};
pub use options::{Filter, StsvOptions};
pub use volume::{build_volumes, stsv_planes, HalfSpace, Stsv, VolumeParams};

use crate::geom::{SceneGeometry, TriangleFrame};
use crate::scene::Scene;
use crate::shade::LightSample;
pub use crate::shadow::kit::rays::ShadowOrigin;
use glam::{DVec2, DVec3, Vec2, Vec3};

/// One S-triangle: a shadow caster with an opacity texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct STriangle {
    /// Its index in the [`SceneGeometry`].
    pub triangle: u32,
    /// Corners in winding order (the f32 world positions, widened).
    pub corners: [DVec3; 3],
    /// Plane and barycentric frame (the geometry's own, so barycentrics
    /// here and in the G-buffer agree).
    pub frame: TriangleFrame,
    /// Texture coordinates of the corners; `None` when the mesh has none,
    /// and then every look-up is at uv (0, 0), as in the reference.
    pub uvs: Option<[DVec2; 3]>,
    /// The material's constant opacity `d`.
    pub opacity: f32,
    /// The opacity texture's index in [`Scene::textures`].
    pub texture: usize,
}

impl STriangle {
    /// Texture coordinates at barycentrics `(b1, b2)` (weights of the
    /// second and third corner), interpolated in f64 exactly as the
    /// reference interpolates them at a ray hit.
    #[inline]
    pub fn uv_at(&self, b1: f32, b2: f32) -> Vec2 {
        match self.uvs {
            Some([i, j, k]) => {
                let (b1, b2) = (f64::from(b1), f64::from(b2));
                (i * (1.0 - b1 - b2) + j * b1 + k * b2).as_vec2()
            }
            None => Vec2::ZERO,
        }
    }

    /// Opacity `d × map_d(uv)` in `[0, 1]` at barycentrics `(b1, b2)`
    /// with `filter`; `d` alone if the texture index is unknown (the
    /// reference's rule).
    pub fn opacity_at(&self, scene: &Scene, b1: f32, b2: f32, filter: Filter) -> f32 {
        let uv = self.uv_at(b1, b2);
        let tex = scene
            .textures
            .get(self.texture)
            .map_or(1.0, |t| match filter {
                Filter::Nearest => t.lookup_scalar(uv),
                Filter::Bilinear => bilinear_scalar(t, uv),
            });
        // The reference multiplies in f32 and clamps; NaN cannot come out
        // of a finite texel, but `clamp` would pass one on, so say 1.
        let o = self.opacity * tex;
        if o.is_nan() {
            1.0
        } else {
            o.clamp(0.0, 1.0)
        }
    }
}

/// Every S-triangle of a scene, in geometry order.
#[derive(Debug, Clone, Default)]
pub struct STriangles {
    /// The S-triangles; an S-triangle's index here is what membership
    /// pairs and look-ups refer to.
    pub list: Vec<STriangle>,
}

impl STriangles {
    /// Every triangle whose object casts shadows and whose material has an
    /// opacity texture. Empty for a scene without any: callers then skip
    /// the whole technique.
    pub fn collect(scene: &Scene, geometry: &SceneGeometry) -> STriangles {
        let mut list = Vec::new();
        for (t, tri) in geometry.triangles.iter().enumerate() {
            let t32 = t as u32;
            let Some(&o) = geometry.triangle_object.get(t) else {
                continue;
            };
            let Some(object) = scene.objects.get(o as usize) else {
                continue;
            };
            let material = geometry
                .triangle_material
                .get(t)
                .and_then(|&m| scene.materials.get(m as usize));
            let (Some(material), true) = (material, object.cast_shadows) else {
                continue;
            };
            let Some(texture) = material.opacity_texture else {
                continue;
            };
            let corner = |i: u32| {
                geometry
                    .positions
                    .get(i as usize)
                    .map_or(DVec3::ZERO, |p| p.as_dvec3())
            };
            let corners = tri.map(corner);
            let frame = TriangleFrame::new(corners);
            list.push(STriangle {
                triangle: t32,
                corners,
                frame,
                uvs: mesh_uvs(scene, geometry, t32),
                opacity: material.opacity,
                texture,
            });
        }
        STriangles { list }
    }

    /// Number of S-triangles.
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// Whether the scene has none.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// Per light sample, the opacity of S-triangle `s` where the segment
    /// from `origin` (a receiver's shadow-ray origin,
    /// [`ShadowOrigin::of`]) to the sample crosses it, 0 where it misses
    /// (and for all samples if `s` is out of range or the origin lies in
    /// the triangle's plane), written to `out` (as many as both slices
    /// hold). SIMD over samples; lays the samples out on every call, which
    /// [`STriangles::sample_opacities_in`] does once per receiver.
    pub fn sample_opacities(
        &self,
        scene: &Scene,
        s: usize,
        origin: Vec3,
        samples: &[LightSample],
        filter: Filter,
        out: &mut [f32],
    ) {
        let mut positions = SamplePositions::default();
        positions.set(samples);
        self.sample_opacities_in(scene, s, origin, &positions, filter, out);
    }

    /// [`STriangles::sample_opacities`] with the samples laid out by
    /// [`SamplePositions::set`] (reused for every S-triangle a receiver
    /// is in).
    pub fn sample_opacities_in(
        &self,
        scene: &Scene,
        s: usize,
        origin: Vec3,
        positions: &SamplePositions,
        filter: Filter,
        out: &mut [f32],
    ) {
        let n = positions.len().min(out.len());
        out[..n].fill(0.0);
        let Some(tri) = self.list.get(s) else {
            return;
        };
        if let Some(projector) = SampleProjector::new(tri, origin) {
            projector.for_each_hit_in(positions, |k, b1, b2| {
                if let Some(o) = out.get_mut(k) {
                    *o = tri.opacity_at(scene, b1, b2, filter);
                }
            });
        }
    }

    /// [`STriangles::sample_opacities`] one sample at a time (the scalar
    /// twin: the same bits).
    pub fn sample_opacities_scalar(
        &self,
        scene: &Scene,
        s: usize,
        origin: Vec3,
        samples: &[LightSample],
        filter: Filter,
        out: &mut [f32],
    ) {
        let n = samples.len().min(out.len());
        out[..n].fill(0.0);
        let Some(tri) = self.list.get(s) else {
            return;
        };
        if let Some(projector) = SampleProjector::new(tri, origin) {
            projector.for_each_hit_scalar(&samples[..n], |k, b1, b2| {
                out[k] = tri.opacity_at(scene, b1, b2, filter);
            });
        }
    }
}

/// The uvs of geometry triangle `t` from its object's mesh, as the
/// reference reads them (`None` if any is missing).
fn mesh_uvs(scene: &Scene, geometry: &SceneGeometry, t: u32) -> Option<[DVec2; 3]> {
    let (o, local) = geometry.locate(t);
    let mesh = &scene.objects.get(o)?.mesh;
    let uvs = mesh.uvs.as_ref()?;
    let [i, j, k] = mesh.triangles.get(local)?;
    Some([
        uvs.get(*i as usize)?.as_dvec2(),
        uvs.get(*j as usize)?.as_dvec2(),
        uvs.get(*k as usize)?.as_dvec2(),
    ])
}

/// An S-triangle for unit tests: `corners`, uvs (0,0), (1,0), (0,1),
/// opacity 1, texture 0.
#[cfg(test)]
pub(crate) fn test_triangle(corners: [DVec3; 3]) -> STriangle {
    STriangle {
        triangle: 0,
        corners,
        frame: TriangleFrame::new(corners),
        uvs: Some([DVec2::ZERO, DVec2::X, DVec2::Y]),
        opacity: 1.0,
        texture: 0,
    }
}
