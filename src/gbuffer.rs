//! The deferred G-buffer: a visibility pass through the rasterizer (depth +
//! triangle id per pixel, see-through texels discarded), then a resolve
//! that rebuilds every shading point exactly where the contract puts it:
//! the camera ray through the pixel centre, intersected in f64 with the
//! triangle the rasterizer found.

use crate::error::Result;
use crate::geom::{SceneGeometry, TriangleFrame};
use crate::raster::{
    draw_numbered, run_vertex_stage_into, ClipVertex, CullMode, DrawStats, FragmentBatch,
    FragmentStage, Framebuffer, NoFragmentStage, RasterState, TileGrid, TiledTarget,
};
use crate::scene::Scene;
use crate::view::View;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use wide::{f64x4, CmpGt, CmpLt};

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
/// `ALPHA`: some material can be see-through, so fragments go through the
/// alpha test; scenes without such materials skip it at compile time.
struct VisibilityStage<'a, const ALPHA: bool> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    view: &'a View,
    /// Per material: can any point of it be see-through for the camera?
    see_through: Vec<bool>,
}

impl<const ALPHA: bool> VisibilityStage<'_, ALPHA> {
    /// Opacity the camera ray through `(x, y)` meets on `triangle`.
    fn opacity_at(&self, triangle: u32, x: u32, y: u32) -> f32 {
        let m = &self.scene.materials[self.geometry.triangle_material[triangle as usize] as usize];
        let dir = self.view.primary_ray_unnormalized(x, y);
        let hit = self.geometry.frames[triangle as usize].hit(self.view.eye, dir);
        let (b1, b2) = hit.map_or((1.0 / 3.0, 1.0 / 3.0), |h| (h.1, h.2));
        let uv = interpolate_uv(self.scene, self.geometry, triangle, b1, b2);
        let tex = m
            .opacity_texture
            .and_then(|t| self.scene.textures.get(t))
            .map_or(1.0, |t| t.lookup_scalar(uv));
        m.opacity * tex
    }
}

impl<const ALPHA: bool> FragmentStage<0> for VisibilityStage<'_, ALPHA> {
    type Target = Box<[u32]>;
    const DISCARDS: bool = ALPHA;

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

/// Whether each object may have its back faces culled in this view: its
/// surface is closed, every material on it stops camera rays, and all its
/// vertices lie beyond twice the near distance. Then the eye is outside it
/// (an eye inside a closed surface has some of the surface behind it) and
/// no near-plane cut opens it, so every back face is hidden by a front
/// face of the same object and culling them changes nothing but the work.
fn cullable_objects(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
) -> Vec<bool> {
    let near = (2.0 * view.near) as f32;
    let camera_opaque = |m: u32| {
        let m = &scene.materials[m as usize];
        m.opacity >= SEE_THROUGH_OPACITY && m.opacity_texture.is_none()
    };
    (0..scene.objects.len())
        .map(|o| {
            let tris = geometry.object_first_triangle[o] as usize
                ..geometry
                    .object_first_triangle
                    .get(o + 1)
                    .map_or(geometry.triangles.len(), |&t| t as usize);
            let verts = geometry.object_first_vertex[o] as usize
                ..geometry
                    .object_first_vertex
                    .get(o + 1)
                    .map_or(vertices.len(), |&v| v as usize);
            geometry.object_closed[o]
                && geometry.triangle_material[tris]
                    .iter()
                    .all(|&m| camera_opaque(m))
                && vertices[verts].iter().all(|v| v.position.w > near)
        })
        .collect()
}

/// Draws the scene's triangles with a closer-wins depth test, culling the
/// back faces of [`cullable_objects`]: one draw per run of objects with the
/// same choice, in object order, so the result equals one draw of all
/// triangles.
fn draw_scene<S: FragmentStage<0>>(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
    fb: &mut Framebuffer,
    targets: &mut [S::Target],
    stage: &S,
) -> Result<DrawStats> {
    let cull = cullable_objects(scene, geometry, view, vertices);
    let mut total = DrawStats::default();
    let mut o = 0;
    while o < cull.len() {
        let mut end = o + 1;
        while end < cull.len() && cull[end] == cull[o] {
            end += 1;
        }
        let first = geometry.object_first_triangle[o] as usize;
        let last = geometry
            .object_first_triangle
            .get(end)
            .map_or(geometry.triangles.len(), |&t| t as usize);
        let state = RasterState {
            cull: if cull[o] {
                CullMode::Back
            } else {
                CullMode::None
            },
            ..RasterState::default()
        };
        let s = draw_numbered(
            fb,
            targets,
            &state,
            vertices,
            &geometry.triangles[first..last],
            first as u32,
            stage,
        )?;
        total += s;
        o = end;
    }
    Ok(total)
}

/// Clip-space vertices of the whole scene.
pub fn transform_vertices(geometry: &SceneGeometry, view: &View) -> Vec<ClipVertex<0>> {
    let mut out = Vec::new();
    transform_vertices_into(geometry, view, &mut out);
    out
}

/// [`transform_vertices`] into a reused vector.
fn transform_vertices_into(geometry: &SceneGeometry, view: &View, out: &mut Vec<ClipVertex<0>>) {
    run_vertex_stage_into(
        &geometry.positions,
        |p| ClipVertex {
            position: view.clip_point(*p),
            varyings: [],
        },
        out,
    )
}

/// Depth-only pass of the whole scene (no see-through handling): the
/// depth pre-pass a hard-shadow renderer runs first.
pub fn depth_pass(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
) -> Result<(Framebuffer, DrawStats)> {
    let grid = TileGrid::new(view.width, view.height)?;
    let mut fb = Framebuffer::new(grid);
    let mut none = vec![(); grid.tile_count()];
    let stats = draw_scene(
        scene,
        geometry,
        view,
        vertices,
        &mut fb,
        &mut none,
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
    let stats = visibility_pass_into(scene, geometry, view, vertices, &mut fb, &mut ids)?;
    Ok((fb, ids, stats))
}

/// The visibility pass into existing, cleared buffers of the view's size.
fn visibility_pass_into(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    vertices: &[ClipVertex<0>],
    fb: &mut Framebuffer,
    ids: &mut TiledTarget<u32>,
) -> Result<DrawStats> {
    let see_through: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| m.opacity < SEE_THROUGH_OPACITY || m.opacity_texture.is_some())
        .collect();
    let tiles = ids.tiles_mut();
    if see_through.iter().any(|&s| s) {
        let stage = VisibilityStage::<true> {
            scene,
            geometry,
            view,
            see_through,
        };
        draw_scene(scene, geometry, view, vertices, fb, tiles, &stage)
    } else {
        let stage = VisibilityStage::<false> {
            scene,
            geometry,
            view,
            see_through,
        };
        draw_scene(scene, geometry, view, vertices, fb, tiles, &stage)
    }
}

/// Resolves triangle ids into shading points (parallel over rows).
pub fn resolve(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
) -> GBuffer {
    let mut gbuffer = GBuffer {
        width: view.width,
        height: view.height,
        samples: vec![GSample::BACKGROUND; view.width as usize * view.height as usize],
    };
    resolve_into(scene, geometry, view, ids, &mut gbuffer);
    gbuffer
}

/// [`resolve`] into an existing G-buffer of the view's size (every pixel
/// is written) with a reusable per-triangle scratch vector.
fn resolve_into(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
    gbuffer: &mut GBuffer,
) {
    let w = view.width;
    let frames = &geometry.frames;
    gbuffer
        .samples
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let mut run: Option<RunTriangle> = None;
            let y = y as u32;
            let mut x = 0u32;
            while x < w {
                let tri = ids.get(x, y);
                if tri == NO_TRIANGLE {
                    row[x as usize] = GSample::BACKGROUND;
                    x += 1;
                    continue;
                }
                // Up to 4 neighbours on the same triangle share one SIMD
                // evaluation.
                let mut end = x + 1;
                while end < w && end - x < 4 && ids.get(end, y) == tri {
                    end += 1;
                }
                // Replaced in place only when the triangle changes: the
                // struct is large, moving it per pixel would cost more than
                // the arithmetic.
                if run.as_ref().is_some_and(|r| r.triangle != tri) {
                    run = None;
                }
                let current = run.get_or_insert_with(|| {
                    RunTriangle::new(scene, geometry, view, frames[tri as usize], tri)
                });
                current.sample4(view, x, y, &mut row[x as usize..end as usize]);
                x = end;
            }
        });
}

/// The G-buffer pass with its buffers, reusable frame after frame the way
/// a GPU keeps its render targets: after the first run nothing is
/// allocated.
pub struct GBufferPass {
    /// Scene depth (and, for later passes, stencil).
    pub framebuffer: Framebuffer,
    /// Triangle id per pixel.
    pub ids: TiledTarget<u32>,
    /// The resolved shading points.
    pub gbuffer: GBuffer,
    vertices: Vec<ClipVertex<0>>,
}

impl GBufferPass {
    /// Buffers for the view's image size.
    pub fn new(view: &View) -> Result<Self> {
        let grid = TileGrid::new(view.width, view.height)?;
        Ok(GBufferPass {
            framebuffer: Framebuffer::new(grid),
            ids: TiledTarget::new(grid, NO_TRIANGLE),
            gbuffer: GBuffer {
                width: view.width,
                height: view.height,
                samples: vec![GSample::BACKGROUND; view.width as usize * view.height as usize],
            },
            vertices: Vec::new(),
        })
    }

    /// Runs the pass for `view` (which must have the size the buffers
    /// were made for).
    pub fn run(
        &mut self,
        scene: &Scene,
        geometry: &SceneGeometry,
        view: &View,
    ) -> Result<DrawStats> {
        if (view.width, view.height) != (self.gbuffer.width, self.gbuffer.height) {
            return Err(crate::error::Error::param(
                "view",
                "the G-buffer pass was made for another image size",
            ));
        }
        self.framebuffer.clear_depth(crate::raster::FAR_DEPTH);
        self.ids.fill(NO_TRIANGLE);
        transform_vertices_into(geometry, view, &mut self.vertices);
        let stats = visibility_pass_into(
            scene,
            geometry,
            view,
            &self.vertices,
            &mut self.framebuffer,
            &mut self.ids,
        )?;
        resolve_into(scene, geometry, view, &self.ids, &mut self.gbuffer);
        Ok(stats)
    }
}

/// The scalar twin of [`resolve`]: one pixel at a time through the same
/// formulas. Kept to test the SIMD path against.
pub fn resolve_scalar(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
) -> GBuffer {
    let (w, h) = (view.width, view.height);
    let mut samples = vec![GSample::BACKGROUND; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let tri = ids.get(x, y);
            if tri != NO_TRIANGLE {
                let t = geometry.triangles[tri as usize]
                    .map(|i| geometry.positions[i as usize].as_dvec3());
                let run = RunTriangle::new(scene, geometry, view, TriangleFrame::new(t), tri);
                samples[(y * w + x) as usize] =
                    run.sample(view, view.primary_ray_unnormalized(x, y));
            }
        }
    }
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
    let mut pass = GBufferPass::new(view)?;
    let stats = pass.run(scene, geometry, view)?;
    Ok((pass.gbuffer, pass.framebuffer, stats))
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

/// A triangle's attributes, gathered once per run of pixels that see it
/// (neighbouring pixels mostly do).
struct RunTriangle<'a> {
    triangle: u32,
    frame: TriangleFrame,
    /// Unit geometric normal from the winding (before facing flips).
    geo_normal: DVec3,
    normals: Option<[DVec3; 3]>,
    uvs: Option<[glam::DVec2; 3]>,
    material: u32,
    albedo: Vec3,
    albedo_texture: Option<&'a crate::scene::Texture>,
    object: u32,
    /// `N · (a - eye)`, the numerator of the ray parameter.
    numerator: f64,
}

impl<'a> RunTriangle<'a> {
    fn new(
        scene: &'a Scene,
        geometry: &SceneGeometry,
        view: &View,
        frame: TriangleFrame,
        triangle: u32,
    ) -> Self {
        let (o, local) = geometry.locate(triangle);
        let mesh = &scene.objects[o].mesh;
        let idx = mesh.triangles[local];
        let material = mesh.material_ids[local];
        let m = &scene.materials[material as usize];
        RunTriangle {
            triangle,
            frame,
            geo_normal: frame.normal.normalize_or_zero(),
            normals: mesh
                .normals
                .as_ref()
                .map(|ns| idx.map(|i| ns[i as usize].as_dvec3())),
            uvs: mesh
                .uvs
                .as_ref()
                .map(|uv| idx.map(|i| uv[i as usize].as_dvec2())),
            material,
            albedo: m.albedo,
            albedo_texture: m.albedo_texture.and_then(|t| scene.textures.get(t)),
            object: o as u32,
            numerator: frame.normal.dot(frame.a - view.eye),
        }
    }

    /// The shading point where the (unnormalised) camera ray `dir` meets
    /// this triangle.
    #[inline]
    fn sample(&self, view: &View, dir: DVec3) -> GSample {
        // Grazing (the ray numerically in the triangle's plane): fall back
        // to the centroid's depth along this ray.
        let (t, b1, b2) = self.frame.hit(view.eye, dir).unwrap_or((
            (self.frame.centroid - view.eye).dot(view.forward),
            1.0 / 3.0,
            1.0 / 3.0,
        ));
        // `dir` has unit length along `forward` (forward + x right + y up),
        // so `t` is the view depth itself.
        let position = view.eye + dir * t;
        // Attributes interpolate with barycentrics clamped into the
        // triangle: pixel centres on an edge may land a rounding error
        // outside it.
        let (cb1, cb2) = (b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0));
        let (cb1, cb2) = if cb1 + cb2 > 1.0 {
            let s = cb1 + cb2;
            (cb1 / s, cb2 / s)
        } else {
            (cb1, cb2)
        };
        let cb0 = 1.0 - cb1 - cb2;
        let mut geo_normal = self.geo_normal;
        let mut normal = match &self.normals {
            Some([i, j, k]) => (*i * cb0 + *j * cb1 + *k * cb2).normalize_or(geo_normal),
            None => geo_normal,
        };
        // A mesh whose vertex normals disagree with its winding (an
        // inverted export) is trusted for its normals: the geometric normal
        // is turned to agree with them first. Then, two-sided surfaces:
        // both normals face the viewer when the geometric one does not
        // (contract, "Surfaces are two-sided").
        if self.normals.is_some() && geo_normal.dot(normal) < 0.0 {
            geo_normal = -geo_normal;
        }
        if geo_normal.dot(view.eye - position) < 0.0 {
            geo_normal = -geo_normal;
            normal = -normal;
        }
        let uv = self.uvs.map_or(Vec2::ZERO, |[i, j, k]| {
            (i * cb0 + j * cb1 + k * cb2).as_vec2()
        });
        let albedo = match self.albedo_texture {
            Some(tex) => self.albedo * tex.lookup_rgb(uv),
            None => self.albedo,
        };
        GSample {
            position: position.as_vec3(),
            normal: normal.as_vec3(),
            geo_normal: geo_normal.as_vec3(),
            uv,
            albedo,
            depth: t as f32,
            material: self.material,
            object: self.object,
            triangle: self.triangle,
        }
    }

    /// Four pixels `(x + k, y)` at once in f64 lanes: the same arithmetic
    /// as [`RunTriangle::sample`], 4 wide. Writes the first `out.len()`
    /// (at most 4) lanes.
    #[inline]
    fn sample4(&self, view: &View, x: u32, y: u32, out: &mut [GSample]) {
        let (w, h) = (view.width as f64, view.height as f64);
        let sx = view.tan_half_fov * w / h;
        let xs = ((f64x4::splat(x as f64) + LANES4 + f64x4::splat(0.5)) * f64x4::splat(2.0 / w)
            - f64x4::splat(1.0))
            * f64x4::splat(sx);
        let ys = (1.0 - 2.0 * (y as f64 + 0.5) / h) * view.tan_half_fov;
        let row = view.forward + ys * view.up;
        let dir = V4::splat(row) + V4::splat(view.right) * xs;
        let n = V4::splat(self.frame.normal);
        let mut t = f64x4::splat(self.numerator) / n.dot(&dir);
        let eye = V4::splat(view.eye);
        let d = eye + dir * t - V4::splat(self.frame.a);
        let mut b1 = d.dot(&V4::splat(self.frame.dual1));
        let mut b2 = d.dot(&V4::splat(self.frame.dual2));
        // Grazing lanes (t not finite or not positive): centroid depth.
        // Finite and positive, by compares alone: `is_finite` on f64 lanes
        // is a 64-bit integer compare, which SSE2 lacks (a scalar loop).
        let ok = t.cmp_gt(f64x4::splat(0.0)) & t.cmp_lt(f64x4::splat(f64::INFINITY));
        let third = f64x4::splat(1.0 / 3.0);
        let centroid_t = f64x4::splat((self.frame.centroid - view.eye).dot(view.forward));
        t = ok.blend(t, centroid_t);
        b1 = ok.blend(b1, third);
        b2 = ok.blend(b2, third);
        let position = eye + dir * t;
        let (zero, one) = (f64x4::splat(0.0), f64x4::splat(1.0));
        let cb1 = b1.max(zero).min(one);
        let cb2 = b2.max(zero).min(one);
        let sum = cb1 + cb2;
        let over = sum.cmp_gt(one);
        let cb1 = over.blend(cb1 / sum, cb1);
        let cb2 = over.blend(cb2 / sum, cb2);
        let cb0 = one - cb1 - cb2;
        let geo = V4::splat(self.geo_normal);
        let (mut geo_normal, mut normal) = match &self.normals {
            Some([i, j, k]) => {
                let m = V4::splat(*i) * cb0 + V4::splat(*j) * cb1 + V4::splat(*k) * cb2;
                let len = m.dot(&m).sqrt();
                let usable = len.cmp_gt(zero) & len.cmp_lt(f64x4::splat(f64::INFINITY));
                let m = m * (one / len);
                let normal = V4::select(usable, &m, &geo);
                // Trust vertex normals over an inverted winding.
                let flip = geo.dot(&normal).cmp_lt(zero);
                (V4::select(flip, &(-geo), &geo), normal)
            }
            None => (geo, geo),
        };
        // Two-sided: face the viewer.
        let away = geo_normal.dot(&(eye - position)).cmp_lt(zero);
        geo_normal = V4::select(away, &(-geo_normal), &geo_normal);
        normal = V4::select(away, &(-normal), &normal);
        let uv = self.uvs.map(|[i, j, k]| {
            let u = f64x4::splat(i.x) * cb0 + f64x4::splat(j.x) * cb1 + f64x4::splat(k.x) * cb2;
            let v = f64x4::splat(i.y) * cb0 + f64x4::splat(j.y) * cb1 + f64x4::splat(k.y) * cb2;
            (u.to_array(), v.to_array())
        });
        let p = position.to_arrays();
        let nn = normal.to_arrays();
        let gn = geo_normal.to_arrays();
        let depth = t.to_array();
        for (k, s) in out.iter_mut().enumerate().take(4) {
            let uv = uv.map_or(Vec2::ZERO, |(u, v)| Vec2::new(u[k] as f32, v[k] as f32));
            let albedo = match self.albedo_texture {
                Some(tex) => self.albedo * tex.lookup_rgb(uv),
                None => self.albedo,
            };
            *s = GSample {
                position: Vec3::new(p[0][k] as f32, p[1][k] as f32, p[2][k] as f32),
                normal: Vec3::new(nn[0][k] as f32, nn[1][k] as f32, nn[2][k] as f32),
                geo_normal: Vec3::new(gn[0][k] as f32, gn[1][k] as f32, gn[2][k] as f32),
                uv,
                albedo,
                depth: depth[k] as f32,
                material: self.material,
                object: self.object,
                triangle: self.triangle,
            };
        }
    }
}

const LANES4: f64x4 = f64x4::new([0.0, 1.0, 2.0, 3.0]);

/// Four 3-vectors in structure-of-arrays form.
#[derive(Clone, Copy)]
struct V4 {
    x: f64x4,
    y: f64x4,
    z: f64x4,
}

impl V4 {
    #[inline]
    fn splat(v: DVec3) -> Self {
        V4 {
            x: f64x4::splat(v.x),
            y: f64x4::splat(v.y),
            z: f64x4::splat(v.z),
        }
    }

    #[inline]
    fn dot(&self, o: &V4) -> f64x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline]
    fn select(mask: f64x4, a: &V4, b: &V4) -> V4 {
        V4 {
            x: mask.blend(a.x, b.x),
            y: mask.blend(a.y, b.y),
            z: mask.blend(a.z, b.z),
        }
    }

    #[inline]
    fn to_arrays(self) -> [[f64; 4]; 3] {
        [self.x.to_array(), self.y.to_array(), self.z.to_array()]
    }
}

impl std::ops::Add for V4 {
    type Output = V4;
    #[inline]
    fn add(self, o: V4) -> V4 {
        V4 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}

impl std::ops::Sub for V4 {
    type Output = V4;
    #[inline]
    fn sub(self, o: V4) -> V4 {
        V4 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}

impl std::ops::Neg for V4 {
    type Output = V4;
    #[inline]
    fn neg(self) -> V4 {
        V4 {
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }
}

impl std::ops::Mul<f64x4> for V4 {
    type Output = V4;
    #[inline]
    fn mul(self, s: f64x4) -> V4 {
        V4 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }
}
