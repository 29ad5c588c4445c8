//! The deferred G-buffer: a visibility pass through the rasterizer (depth +
//! triangle id per pixel, see-through texels discarded), then a resolve
//! that rebuilds every shading point exactly where the contract puts it:
//! the camera ray through the pixel centre, intersected in f64 with the
//! triangle the rasterizer found.

mod resolve;

pub use resolve::{resolve, resolve_scalar};

use crate::error::Result;
use crate::geom::SceneGeometry;
use crate::raster::{
    draw_numbered, run_vertex_stage_into, ClipVertex, CullMode, DrawStats, FragmentBatch,
    FragmentStage, Framebuffer, NoFragmentStage, RasterState, TileGrid, TiledTarget,
};
use crate::scene::Scene;
use crate::view::View;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// Triangle id of pixels where no surface is seen.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Camera rays pass through a surface where its opacity is below this
/// (contract, "Camera rays and non-opaque surfaces").
pub const SEE_THROUGH_OPACITY: f32 = 0.5;

/// One shading point, as consumers see it: [`GBuffer::sample`] expands
/// the stored pixel (see [`GBuffer`]) into this.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GSample {
    /// World position: the camera ray's hit on the triangle (f64 solve).
    pub position: Vec3,
    /// Shading normal, unit, facing the viewer.
    pub normal: Vec3,
    /// Geometric normal, unit, facing the viewer.
    pub geo_normal: Vec3,
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

/// Bit of [`GPoint::triangle`] set when the pixel's geometric normal is
/// its triangle's winding normal negated.
const GEO_FLIPPED: u32 = 1 << 31;

/// Triangle ids must stay below this, so that the flag bit never makes a
/// surface pixel look like [`NO_TRIANGLE`].
const MAX_TRIANGLES: usize = (GEO_FLIPPED - 1) as usize;

/// One pixel as the G-buffer stores it (32 bytes): what only this pixel
/// knows, as two 16-byte lanes the resolve writes whole. Everything a
/// triangle or material determines is looked up on expansion.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(16))]
struct GPoint {
    /// World position (f64 solve, rounded) and view depth (the ray
    /// parameter, rounded).
    position_depth: [f32; 4],
    /// Shading normal (unit, facing the viewer) and the bits of the
    /// triangle index, [`GEO_FLIPPED`] or-ed in; [`NO_TRIANGLE`] for
    /// background.
    normal_triangle: [f32; 4],
}

impl GPoint {
    const BACKGROUND: GPoint = GPoint {
        position_depth: [0.0; 4],
        normal_triangle: [0.0, 0.0, 0.0, f32::from_bits(NO_TRIANGLE)],
    };

    /// A surface pixel.
    fn new(position: Vec3, depth: f32, normal: Vec3, triangle: u32) -> Self {
        GPoint {
            position_depth: [position.x, position.y, position.z, depth],
            normal_triangle: [normal.x, normal.y, normal.z, f32::from_bits(triangle)],
        }
    }

    /// From lanes `[x, y, z, depth]` and `[nx, ny, nz, triangle bits]`.
    #[inline(always)]
    fn from_lanes(position_depth: crate::simd::f32x4, normal_triangle: crate::simd::f32x4) -> Self {
        GPoint {
            position_depth: position_depth.to_array(),
            normal_triangle: normal_triangle.to_array(),
        }
    }

    /// The triangle bits (index and flag).
    #[inline(always)]
    fn triangle(&self) -> u32 {
        self.normal_triangle[3].to_bits()
    }
}

/// The resolved G-buffer, row-major, row 0 at the top.
///
/// Stored compactly: per pixel the exact position, view depth, shading
/// normal and triangle (32 bytes), plus the albedo only for scenes with
/// albedo textures. Material, object and geometric normal come from the
/// triangle (tables shared with [`SceneGeometry`]) when a pixel is read
/// with [`GBuffer::sample`].
#[derive(Debug, Clone)]
pub struct GBuffer {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    points: Vec<GPoint>,
    /// Per-pixel albedo when some material has an albedo texture, else
    /// empty (the material's albedo is the pixel's).
    albedo: Vec<Vec3>,
    /// Per material, its albedo.
    material_albedo: Vec<Vec3>,
    /// The geometry's per-triangle tables.
    unit_normals: Arc<[Vec3]>,
    triangle_material: Arc<[u32]>,
    triangle_object: Arc<[u32]>,
    /// After [`GBuffer::keep_rows`], the whole frame's surface positions
    /// in pixel order ([`GBuffer::frame_surfaces`]); `None` for a whole
    /// frame.
    frame_surfaces: Option<Vec<Vec3>>,
}

impl GBuffer {
    /// Bytes its per-pixel arrays hold.
    pub fn memory_bytes(&self) -> u64 {
        (self.points.len() * std::mem::size_of::<GPoint>() + self.albedo.len() * 12) as u64
    }

    /// A G-buffer of the view's size, every pixel background, bound to
    /// no scene yet.
    fn blank(view: &View) -> Self {
        GBuffer {
            width: view.width,
            height: view.height,
            points: vec![GPoint::BACKGROUND; view.width as usize * view.height as usize],
            albedo: Vec::new(),
            material_albedo: Vec::new(),
            unit_normals: Arc::from([]),
            triangle_material: Arc::from([]),
            triangle_object: Arc::from([]),
            frame_surfaces: None,
        }
    }

    /// Points the G-buffer at `scene`'s tables (allocating the albedo
    /// plane the first time a scene needs one).
    fn bind(&mut self, scene: &Scene, geometry: &SceneGeometry) -> Result<()> {
        if geometry.triangles.len() > MAX_TRIANGLES {
            return Err(crate::error::Error::param(
                "scene",
                format!(
                    "{} triangles; the G-buffer addresses at most {MAX_TRIANGLES}",
                    geometry.triangles.len()
                ),
            ));
        }
        self.unit_normals = geometry.unit_normals.clone();
        self.triangle_material = geometry.triangle_material.clone();
        self.triangle_object = geometry.triangle_object.clone();
        self.material_albedo.clear();
        self.material_albedo
            .extend(scene.materials.iter().map(|m| m.albedo));
        if has_albedo_textures(scene) {
            self.albedo
                .resize(self.width as usize * self.height as usize, Vec3::ZERO);
        } else {
            self.albedo = Vec::new();
        }
        Ok(())
    }

    /// Makes every pixel outside `rows` background, so that a band render
    /// (`render --tiles`, [`crate::cluster::tiles`]) shades and traces
    /// only its own rows; the pixels inside keep their bits.
    pub fn keep_rows(&mut self, rows: std::ops::Range<u32>) {
        if self.frame_surfaces.is_none() {
            self.frame_surfaces = Some(self.frame_surfaces().collect());
        }
        let width = self.width as usize;
        for (y, row) in self.points.chunks_mut(width).enumerate() {
            if !rows.contains(&(y as u32)) {
                row.fill(GPoint::BACKGROUND);
            }
        }
    }

    /// The whole frame's surface positions in pixel order, also after
    /// [`GBuffer::keep_rows`] made a band: decisions made for the whole
    /// frame (DCS's cost choice) read them, so that every band of a frame
    /// makes the one the whole frame makes and its pixels keep their bits.
    pub fn frame_surfaces(&self) -> Box<dyn Iterator<Item = Vec3> + '_> {
        match &self.frame_surfaces {
            Some(positions) => Box::new(positions.iter().copied()),
            None => Box::new((0..self.len()).filter_map(|i| self.surface_position(i))),
        }
    }

    /// Number of pixels.
    #[inline]
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the image has no pixels (never, for a valid view).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Whether pixel `i` (row-major) sees a surface.
    #[inline]
    pub fn is_surface(&self, i: usize) -> bool {
        self.points[i].triangle() != NO_TRIANGLE
    }

    /// Pixel `i`'s surface position, `None` on the background: what
    /// [`GBuffer::sample`] gives as `position`, without reading the rest
    /// (the culling's boxes read millions of positions).
    #[inline]
    pub fn surface_position(&self, i: usize) -> Option<Vec3> {
        let p = &self.points[i];
        if p.triangle() == NO_TRIANGLE {
            return None;
        }
        let [x, y, z, _] = p.position_depth;
        Some(Vec3::new(x, y, z))
    }

    /// Pixel `i`'s surface position, geometric normal and triangle,
    /// `None` on the background: [`GBuffer::sample`]'s fields of those
    /// names, without reading the rest.
    #[inline]
    pub fn surface_geometry(&self, i: usize) -> Option<(Vec3, Vec3, u32)> {
        let p = &self.points[i];
        let bits = p.triangle();
        if bits == NO_TRIANGLE {
            return None;
        }
        let triangle = bits & !GEO_FLIPPED;
        let [x, y, z, _] = p.position_depth;
        let unit = self.unit_normals[triangle as usize];
        let geo_normal = if bits & GEO_FLIPPED != 0 { -unit } else { unit };
        Some((Vec3::new(x, y, z), geo_normal, triangle))
    }

    /// The shading point of pixel `i` (row-major).
    #[inline]
    pub fn sample(&self, i: usize) -> GSample {
        let p = self.points[i];
        let bits = p.triangle();
        if bits == NO_TRIANGLE {
            return GSample::BACKGROUND;
        }
        let triangle = bits & !GEO_FLIPPED;
        let [x, y, z, depth] = p.position_depth;
        let [nx, ny, nz, _] = p.normal_triangle;
        let t = triangle as usize;
        let unit = self.unit_normals[t];
        let material = self.triangle_material[t];
        GSample {
            position: Vec3::new(x, y, z),
            normal: Vec3::new(nx, ny, nz),
            geo_normal: if bits & GEO_FLIPPED != 0 { -unit } else { unit },
            albedo: match self.albedo.get(i) {
                Some(&a) => a,
                None => self.material_albedo[material as usize],
            },
            depth,
            material,
            object: self.triangle_object[t],
            triangle,
        }
    }

    /// The shading point of pixel `i`, `None` outside the image.
    #[inline]
    pub fn get(&self, i: usize) -> Option<GSample> {
        (i < self.len()).then(|| self.sample(i))
    }

    /// The shading point at pixel `(x, y)`.
    #[inline]
    pub fn at(&self, x: u32, y: u32) -> GSample {
        self.sample((y * self.width + x) as usize)
    }

    /// Every pixel's shading point, row-major.
    pub fn samples(&self) -> impl ExactSizeIterator<Item = GSample> + '_ {
        (0..self.len()).map(|i| self.sample(i))
    }

    /// [`GBuffer::samples`] as a parallel iterator.
    pub fn par_samples(&self) -> impl IndexedParallelIterator<Item = GSample> + '_ {
        (0..self.len()).into_par_iter().map(|i| self.sample(i))
    }

    /// Bytes the G-buffer stores per pixel for `scene`.
    pub fn bytes_per_pixel(scene: &Scene) -> usize {
        std::mem::size_of::<GPoint>()
            + if has_albedo_textures(scene) {
                std::mem::size_of::<Vec3>()
            } else {
                0
            }
    }
}

/// Whether some material of `scene` has an albedo texture (then the
/// G-buffer keeps a per-pixel albedo).
fn has_albedo_textures(scene: &Scene) -> bool {
    scene
        .materials
        .iter()
        .any(|m| m.albedo_texture.is_some_and(|t| t < scene.textures.len()))
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
        let hit = self.geometry.frame(triangle).hit(self.view.eye, dir);
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
        if batch.mask == 0xff {
            ids[batch.local..batch.local + 8].fill(batch.primitive);
            return;
        }
        let mut mask = batch.mask;
        while mask != 0 {
            ids[batch.local + mask.trailing_zeros() as usize] = batch.primitive;
            mask &= mask - 1;
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
            let tris = geometry.object_triangle_range(o);
            let verts = geometry.object_vertex_range(o);
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
        let (first, last) = (
            geometry.object_triangle_range(o).start,
            geometry.object_triangle_range(end - 1).end,
        );
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
    /// The resolve's per-column ray table.
    columns: resolve::Columns,
}

impl GBufferPass {
    /// Buffers for the view's image size.
    pub fn new(view: &View) -> Result<Self> {
        let grid = TileGrid::new(view.width, view.height)?;
        Ok(GBufferPass {
            framebuffer: Framebuffer::new(grid),
            ids: TiledTarget::new(grid, NO_TRIANGLE),
            gbuffer: GBuffer::blank(view),
            vertices: Vec::new(),
            columns: resolve::Columns::default(),
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
        let (framebuffer, ids) = (&mut self.framebuffer, &mut self.ids);
        rayon::join(
            || framebuffer.clear_depth(crate::raster::FAR_DEPTH),
            || {
                ids.tiles_mut()
                    .par_iter_mut()
                    .for_each(|t| t.fill(NO_TRIANGLE))
            },
        );
        transform_vertices_into(geometry, view, &mut self.vertices);
        let stats = visibility_pass_into(
            scene,
            geometry,
            view,
            &self.vertices,
            &mut self.framebuffer,
            &mut self.ids,
        )?;
        self.gbuffer.bind(scene, geometry)?;
        resolve::resolve_into(
            scene,
            geometry,
            view,
            &self.ids,
            &mut self.gbuffer,
            &mut self.columns,
        );
        Ok(stats)
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

/// Texture coordinates of `triangle` at barycentrics `(b1, b2)` (f64
/// interpolation, 0 when the mesh has none).
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
