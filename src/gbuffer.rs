//! The deferred G-buffer: a visibility pass through the rasterizer (depth +
//! triangle id per pixel, see-through texels discarded), then a resolve
//! that rebuilds every shading point exactly where the contract puts it:
//! the camera ray through the pixel centre, intersected in f64 with the
//! triangle the rasterizer found.

use crate::error::Result;
use crate::geom::SceneGeometry;
use crate::raster::{
    draw, run_vertex_stage, ClipVertex, DrawStats, FragmentBatch, FragmentStage, Framebuffer,
    NoFragmentStage, RasterState, TileGrid, TiledTarget,
};
use crate::scene::Scene;
use crate::view::View;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

/// Triangle id of pixels where no surface is seen.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Camera rays pass through a surface where its opacity is below this
/// (contract, "Camera rays and non-opaque surfaces").
pub const SEE_THROUGH_OPACITY: f32 = 0.5;

/// One shading point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GSample {
    /// World position: the camera ray's hit on the triangle (f64 solve).
    pub position: Vec3,
    /// Shading normal, unit, facing the viewer.
    pub normal: Vec3,
    /// Geometric normal, unit, facing the viewer.
    pub geo_normal: Vec3,
    /// Texture coordinates (0 when the mesh has none).
    pub uv: Vec2,
    /// Albedo with its texture applied, linear RGB.
    pub albedo: Vec3,
    /// View-space depth along the camera's forward axis.
    pub depth: f32,
    /// Material index.
    pub material: u32,
    /// Object index.
    pub object: u32,
    /// Triangle index in [`SceneGeometry`], [`NO_TRIANGLE`] for background.
    pub triangle: u32,
}

impl GSample {
    /// A background pixel.
    pub const BACKGROUND: GSample = GSample {
        position: Vec3::ZERO,
        normal: Vec3::ZERO,
        geo_normal: Vec3::ZERO,
        uv: Vec2::ZERO,
        albedo: Vec3::ZERO,
        depth: 0.0,
        material: 0,
        object: 0,
        triangle: NO_TRIANGLE,
    };

    /// Whether a surface is seen here.
    #[inline]
    pub fn is_surface(&self) -> bool {
        self.triangle != NO_TRIANGLE
    }
}

/// The resolved G-buffer, row-major, row 0 at the top.
#[derive(Debug, Clone)]
pub struct GBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// One sample per pixel.
    pub samples: Vec<GSample>,
}

impl GBuffer {
    /// The sample at pixel `(x, y)`.
    #[inline]
    pub fn at(&self, x: u32, y: u32) -> &GSample {
        &self.samples[(y * self.width + x) as usize]
    }
}

/// Writes triangle ids; discards texels a camera ray passes through.
struct VisibilityStage<'a> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    view: &'a View,
    /// Per material: can any point of it be see-through for the camera?
    see_through: Vec<bool>,
}

impl VisibilityStage<'_> {
    /// Opacity the camera ray through `(x, y)` meets on `triangle`.
    fn opacity_at(&self, triangle: u32, x: u32, y: u32) -> f32 {
        let m = &self.scene.materials[self.geometry.triangle_material[triangle as usize] as usize];
        let dir = self.view.primary_ray(x, y);
        let hit = intersect(self.view.eye, dir, self.corners(triangle));
        let (b1, b2) = hit.map_or((0.0, 0.0), |h| (h.1, h.2));
        let uv = interpolate_uv(self.scene, self.geometry, triangle, b1, b2);
        let tex = m
            .opacity_texture
            .and_then(|t| self.scene.textures.get(t))
            .map_or(1.0, |t| t.lookup_scalar(uv));
        m.opacity * tex
    }

    fn corners(&self, triangle: u32) -> [DVec3; 3] {
        self.geometry.triangles[triangle as usize]
            .map(|i| self.geometry.positions[i as usize].as_dvec3())
    }
}

impl FragmentStage<0> for VisibilityStage<'_> {
    type Target = Box<[u32]>;
    const DISCARDS: bool = true;

    fn discard(&self, batch: &FragmentBatch<0>) -> u8 {
        let material = self.geometry.triangle_material[batch.primitive as usize] as usize;
        if !self.see_through[material] {
            return batch.mask;
        }
        let mut mask = batch.mask;
        for k in batch.lanes() {
            let (x, y) = ((batch.x + k as i32) as u32, batch.y as u32);
            if self.opacity_at(batch.primitive, x, y) < SEE_THROUGH_OPACITY {
                mask &= !(1 << k);
            }
        }
        mask
    }

    fn shade(&self, batch: &FragmentBatch<0>, ids: &mut Box<[u32]>) {
        for k in batch.lanes() {
            ids[batch.local + k] = batch.primitive;
        }
    }
}

/// Clip-space vertices of the whole scene.
pub fn transform_vertices(geometry: &SceneGeometry, view: &View) -> Vec<ClipVertex<0>> {
    run_vertex_stage(&geometry.positions, |p| ClipVertex {
        position: view.clip_point(*p),
        varyings: [],
    })
}

/// Depth-only pass of the whole scene (no see-through handling): the
/// depth pre-pass a hard-shadow renderer runs first.
pub fn depth_pass(
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
) -> Result<(Framebuffer, DrawStats)> {
    let grid = TileGrid::new(view.width, view.height)?;
    let mut fb = Framebuffer::new(grid);
    let mut none = vec![(); grid.tile_count()];
    let stats = draw(
        &mut fb,
        &mut none,
        &RasterState::default(),
        vertices,
        &geometry.triangles,
        &NoFragmentStage,
    )?;
    Ok((fb, stats))
}

/// Visibility pass: depth and triangle id per pixel.
pub fn visibility_pass(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
) -> Result<(Framebuffer, TiledTarget<u32>, DrawStats)> {
    let grid = TileGrid::new(view.width, view.height)?;
    let mut fb = Framebuffer::new(grid);
    let mut ids = TiledTarget::new(grid, NO_TRIANGLE);
    let stage = VisibilityStage {
        scene,
        geometry,
        view,
        see_through: scene
            .materials
            .iter()
            .map(|m| m.opacity < SEE_THROUGH_OPACITY || m.opacity_texture.is_some())
            .collect(),
    };
    let stats = draw(
        &mut fb,
        ids.tiles_mut(),
        &RasterState::default(),
        vertices,
        &geometry.triangles,
        &stage,
    )?;
    Ok((fb, ids, stats))
}

/// Resolves triangle ids into shading points (parallel over rows).
pub fn resolve(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
) -> GBuffer {
    let (w, h) = (view.width, view.height);
    let mut samples = vec![GSample::BACKGROUND; (w * h) as usize];
    samples
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, s) in row.iter_mut().enumerate() {
                let tri = ids.get(x as u32, y as u32);
                if tri != NO_TRIANGLE {
                    *s = shading_point(scene, geometry, view, tri, x as u32, y as u32);
                }
            }
        });
    GBuffer {
        width: w,
        height: h,
        samples,
    }
}

/// The full G-buffer pass: visibility, then resolve.
pub fn gbuffer_pass(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
) -> Result<(GBuffer, Framebuffer, DrawStats)> {
    let vertices = transform_vertices(geometry, view);
    let (fb, ids, stats) = visibility_pass(scene, geometry, view, &vertices)?;
    Ok((resolve(scene, geometry, view, &ids), fb, stats))
}

/// Möller–Trumbore in f64 without range checks on the barycentrics:
/// returns `(t, b1, b2)` of the ray's hit on the triangle's plane.
#[inline]
pub fn intersect(origin: DVec3, dir: DVec3, [a, b, c]: [DVec3; 3]) -> Option<(f64, f64, f64)> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = dir.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv = origin - a;
    let b1 = tv.dot(pv) * inv;
    let qv = tv.cross(e1);
    let b2 = dir.dot(qv) * inv;
    let t = e2.dot(qv) * inv;
    (t.is_finite() && t > 0.0).then_some((t, b1, b2))
}

fn interpolate_uv(
    scene: &Scene,
    geometry: &SceneGeometry,
    triangle: u32,
    b1: f64,
    b2: f64,
) -> Vec2 {
    let (o, local) = geometry.locate(triangle);
    let mesh = &scene.objects[o].mesh;
    let Some(uvs) = &mesh.uvs else {
        return Vec2::ZERO;
    };
    let [i, j, k] = mesh.triangles[local].map(|i| uvs[i as usize].as_dvec2());
    let b0 = 1.0 - b1 - b2;
    (i * b0 + j * b1 + k * b2).as_vec2()
}

/// Rebuilds the shading point of pixel `(x, y)` on `triangle`.
fn shading_point(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    triangle: u32,
    x: u32,
    y: u32,
) -> GSample {
    let (o, local) = geometry.locate(triangle);
    let mesh = &scene.objects[o].mesh;
    let corners = mesh.triangles[local].map(|i| mesh.positions[i as usize].as_dvec3());
    let dir = view.primary_ray(x, y);
    let (position, b1, b2) = match intersect(view.eye, dir, corners) {
        Some((t, b1, b2)) => (view.eye + dir * t, b1, b2),
        // Grazing: the ray is (numerically) in the triangle's plane. Fall
        // back to the centroid's depth along this ray.
        None => {
            let c = (corners[0] + corners[1] + corners[2]) / 3.0;
            let t = view.depth_of(c) / dir.dot(view.forward);
            (view.eye + dir * t, 1.0 / 3.0, 1.0 / 3.0)
        }
    };
    // Attributes interpolate with barycentrics clamped into the triangle:
    // pixel centres on an edge may land a rounding error outside it.
    let (cb1, cb2) = (b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0));
    let (cb1, cb2) = if cb1 + cb2 > 1.0 {
        let s = cb1 + cb2;
        (cb1 / s, cb2 / s)
    } else {
        (cb1, cb2)
    };
    let cb0 = 1.0 - cb1 - cb2;
    let mut geo_normal = (corners[1] - corners[0])
        .cross(corners[2] - corners[0])
        .normalize_or_zero();
    let mut normal = match &mesh.normals {
        Some(ns) => {
            let [i, j, k] = mesh.triangles[local].map(|i| ns[i as usize].as_dvec3());
            (i * cb0 + j * cb1 + k * cb2).normalize_or(geo_normal)
        }
        None => geo_normal,
    };
    // A mesh whose vertex normals disagree with its winding (an inverted
    // export) is trusted for its normals: the geometric normal is turned to
    // agree with them first. Then, two-sided surfaces: both normals face
    // the viewer when the geometric one does not (contract, "Surfaces are
    // two-sided").
    if mesh.normals.is_some() && geo_normal.dot(normal) < 0.0 {
        geo_normal = -geo_normal;
    }
    if geo_normal.dot(view.eye - position) < 0.0 {
        geo_normal = -geo_normal;
        normal = -normal;
    }
    let uv = interpolate_uv(scene, geometry, triangle, cb1, cb2);
    let material_index = mesh.material_ids[local];
    let m = &scene.materials[material_index as usize];
    let tex = m
        .albedo_texture
        .and_then(|t| scene.textures.get(t))
        .map_or(Vec3::ONE, |t| t.lookup_rgb(uv));
    GSample {
        position: position.as_vec3(),
        normal: normal.as_vec3(),
        geo_normal: geo_normal.as_vec3(),
        uv,
        albedo: m.albedo * tex,
        depth: view.depth_of(position) as f32,
        material: material_index,
        object: o as u32,
        triangle,
    }
}
