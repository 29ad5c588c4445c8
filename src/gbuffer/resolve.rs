//! The resolve: every pixel's triangle id becomes its exact shading point,
//! the contract's camera ray through the pixel centre intersected in f64
//! with the triangle's plane.
//!
//! Rows run in parallel; inside a row, the ids are read tile by tile and
//! cut into runs of one triangle. A run's triangle is prepared once, then
//! its pixels go four at a time through f64 lanes. Triangles without vertex
//! normals or textures need no barycentrics: their normal is the run's.
//! [`resolve_scalar`] is the same arithmetic one pixel at a time, kept to
//! test the lanes against.

use super::{interpolate_uv, GBuffer, GPoint, GEO_FLIPPED, NO_TRIANGLE};
use crate::error::Result;
use crate::geom::{SceneGeometry, TriangleFrame};
use crate::raster::{TiledTarget, TILE_SIZE};
use crate::scene::{Scene, Texture};
use crate::view::View;
use bytemuck::cast;
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use wide::{f32x4, f64x4, u32x4, CmpGt, CmpLt};

/// Pixels per lane group.
const LANES: usize = 4;

/// Image rows per parallel task.
const ROWS_PER_TASK: usize = 4;

/// Resolves triangle ids into shading points (parallel over rows).
pub fn resolve(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
) -> Result<GBuffer> {
    let mut gbuffer = GBuffer::blank(view);
    gbuffer.bind(scene, geometry)?;
    resolve_into(
        scene,
        geometry,
        view,
        ids,
        &mut gbuffer,
        &mut Columns::default(),
    );
    Ok(gbuffer)
}

/// Per image column `x`, the part `right * xs(x)` of the primary ray's
/// direction (`forward + ys up + xs right`), one plane per axis, padded so
/// that a group of [`LANES`] may start at any column.
#[derive(Debug, Default, Clone)]
pub(super) struct Columns {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
}

impl Columns {
    /// The table for `view` (reusing the vectors).
    fn fill(&mut self, view: &View) {
        let (w, h) = (view.width as f64, view.height as f64);
        let sx = view.tan_half_fov * w / h;
        let n = view.width as usize + LANES - 1;
        for plane in [&mut self.x, &mut self.y, &mut self.z] {
            plane.clear();
        }
        for i in 0..n {
            let xs = ((i as f64 + 0.5) * (2.0 / w) - 1.0) * sx;
            self.x.push(view.right.x * xs);
            self.y.push(view.right.y * xs);
            self.z.push(view.right.z * xs);
        }
    }

    /// Columns `x .. x + LANES`.
    #[inline(always)]
    fn lanes(&self, x: usize) -> V4 {
        let load = |p: &[f64]| {
            let a: [f64; LANES] = p[x..x + LANES].try_into().expect("padded table");
            f64x4::from(a)
        };
        V4 {
            x: load(&self.x),
            y: load(&self.y),
            z: load(&self.z),
        }
    }
}

/// [`resolve`] into a G-buffer of the view's size, bound to `scene`
/// (every pixel is written), with a reusable column table.
pub(super) fn resolve_into(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
    gbuffer: &mut GBuffer,
    columns: &mut Columns,
) {
    columns.fill(view);
    let ctx = Ctx {
        scene,
        geometry,
        view,
        columns,
    };
    let w = view.width as usize;
    let task = w * ROWS_PER_TASK;
    let rows = |(c, (points, albedo)): (usize, (&mut [GPoint], &mut [Vec3]))| {
        for (r, row) in points.chunks_mut(w).enumerate() {
            let albedo = if albedo.is_empty() {
                &mut [][..]
            } else {
                &mut albedo[r * w..(r + 1) * w]
            };
            ctx.row(ids, c * ROWS_PER_TASK + r, row, albedo);
        }
    };
    if gbuffer.albedo.is_empty() {
        gbuffer
            .points
            .par_chunks_mut(task)
            .map(|p| (p, &mut [][..]))
            .enumerate()
            .for_each(rows);
    } else {
        gbuffer
            .points
            .par_chunks_mut(task)
            .zip(gbuffer.albedo.par_chunks_mut(task))
            .enumerate()
            .for_each(rows);
    }
}

/// What every row of one resolve shares.
struct Ctx<'a> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    view: &'a View,
    columns: &'a Columns,
}

impl Ctx<'_> {
    /// Resolves image row `y` into `out` (and `albedo`, when the G-buffer
    /// keeps it; else empty).
    fn row(&self, ids: &TiledTarget<u32>, y: usize, out: &mut [GPoint], albedo: &mut [Vec3]) {
        let view = self.view;
        let h = view.height as f64;
        let ys = (1.0 - 2.0 * (y as f64 + 0.5) / h) * view.tan_half_fov;
        let row = V4::splat(view.forward + ys * view.up);
        let eye = V4::splat(view.eye);
        let grid = ids.grid();
        let (ty, ly) = (y / TILE_SIZE, y % TILE_SIZE);
        let w = out.len();
        let textured = !albedo.is_empty();
        // Replaced only when the triangle changes: runs of one triangle
        // split at tile borders share it.
        let mut run: Option<RunTriangle> = None;
        for tx in 0..grid.tiles_x {
            let x0 = tx * TILE_SIZE;
            let n = TILE_SIZE.min(w - x0);
            let tile = &ids.tile(ty * grid.tiles_x + tx)[ly * TILE_SIZE..][..n];
            let mut i = 0;
            while i < n {
                let tri = tile[i];
                let mut j = i + 1;
                while j < n && tile[j] == tri {
                    j += 1;
                }
                let (a, b) = (x0 + i, x0 + j);
                i = j;
                if tri == NO_TRIANGLE {
                    out[a..b].fill(GPoint::BACKGROUND);
                    continue;
                }
                let r = match &mut run {
                    Some(r) if r.id == tri => r,
                    slot => slot.insert(RunTriangle::new(self, tri, textured)),
                };
                let mut x = a;
                while x < b {
                    let end = (x + LANES).min(b);
                    let lanes = Lanes {
                        dir: row + self.columns.lanes(x),
                        eye,
                    };
                    let out = &mut out[x..end];
                    if textured {
                        lanes.textured(r, out, &mut albedo[x..end]);
                    } else if let Some(s) = &r.smooth {
                        lanes.smooth(r, s, out);
                    } else {
                        lanes.flat(r, out);
                    }
                    x = end;
                }
            }
        }
    }
}

/// Up to [`LANES`] pixels of one row on one triangle: their rays.
struct Lanes {
    /// Unnormalised ray directions.
    dir: V4,
    eye: V4,
}

/// Where a group of rays meets its triangle's plane.
struct Hits {
    /// `eye + dir t` before the grazing fallback (barycentrics use it).
    hit: V4,
    /// Lanes whose hit is usable (finite, in front of the eye).
    ok: f64x4,
    /// Every lane is.
    all_ok: bool,
    /// Rounded position and depth per lane: `[x, y, z, depth]`.
    position_depth: [f32x4; LANES],
}

impl Lanes {
    /// The ray parameters and positions, with grazing lanes (t not finite
    /// or not positive) at the centroid's depth along their ray.
    #[inline(always)]
    fn hits(&self, r: &RunTriangle) -> Hits {
        let t = r.numerator / r.normal.dot(&self.dir);
        let hit = self.eye + self.dir * t;
        // Finite and positive by compares alone: `is_finite` on f64 lanes
        // is a 64-bit integer compare, which SSE2 lacks.
        let ok = t.cmp_gt(f64x4::splat(0.0)) & t.cmp_lt(f64x4::splat(f64::INFINITY));
        let all_ok = ok.move_mask() == 0b1111;
        let (t, position) = if all_ok {
            (t, hit)
        } else {
            let t = ok.blend(t, r.centroid_t);
            (t, self.eye + self.dir * t)
        };
        Hits {
            hit,
            ok,
            all_ok,
            position_depth: f32x4::transpose([
                narrow(position.x),
                narrow(position.y),
                narrow(position.z),
                narrow(t),
            ]),
        }
    }

    /// A triangle without vertex normals: the run's normal.
    #[inline(always)]
    fn flat(&self, r: &RunTriangle, out: &mut [GPoint]) {
        let h = self.hits(r);
        for (o, pd) in out.iter_mut().zip(h.position_depth) {
            *o = GPoint::from_lanes(pd, r.flat);
        }
    }

    /// Barycentrics of the hits (f64), grazing lanes at the centroid.
    #[inline(always)]
    fn barycentrics(&self, r: &RunTriangle, h: &Hits) -> (f64x4, f64x4) {
        let d = h.hit - r.a;
        let (b1, b2) = (d.dot(&r.dual1), d.dot(&r.dual2));
        if h.all_ok {
            (b1, b2)
        } else {
            let third = f64x4::splat(1.0 / 3.0);
            (h.ok.blend(b1, third), h.ok.blend(b2, third))
        }
    }

    /// A triangle with vertex normals.
    #[inline(always)]
    fn smooth(&self, r: &RunTriangle, s: &Smooth, out: &mut [GPoint]) {
        let h = self.hits(r);
        let (b1, b2) = self.barycentrics(r, &h);
        store_smooth(r, s, &h, b1, b2, out);
    }

    /// A scene with albedo textures: as [`Lanes::smooth`] or
    /// [`Lanes::flat`], and the albedo per lane from f64 uvs.
    fn textured(&self, r: &RunTriangle, out: &mut [GPoint], albedo: &mut [Vec3]) {
        let h = self.hits(r);
        let (b1, b2) = self.barycentrics(r, &h);
        match &r.smooth {
            Some(s) => store_smooth(r, s, &h, b1, b2, out),
            None => {
                for (o, pd) in out.iter_mut().zip(h.position_depth) {
                    *o = GPoint::from_lanes(pd, r.flat);
                }
            }
        }
        let (b1, b2) = (b1.to_array(), b2.to_array());
        for (k, a) in albedo.iter_mut().enumerate() {
            let (cb1, cb2) = clamp_barycentrics(b1[k], b2[k], 0.0, 1.0);
            *a = r.albedo.as_ref().map_or(Vec3::ZERO, |al| al.at(cb1, cb2));
        }
    }
}

/// Stores the lanes of a smooth triangle: shading normals facing the
/// viewer, ids with their geometric-normal flags.
#[inline(always)]
fn store_smooth(r: &RunTriangle, s: &Smooth, h: &Hits, b1: f64x4, b2: f64x4, out: &mut [GPoint]) {
    let (normal, turned) = s.normals(narrow(b1), narrow(b2));
    let away = turned.blend(r.front, r.back);
    let sign = away & f32x4::splat(-0.0);
    let flag: f32x4 = cast(u32x4::splat(GEO_FLIPPED));
    let id: u32x4 = u32x4::splat(r.id) | cast::<f32x4, u32x4>((turned ^ away) & flag);
    let nt = f32x4::transpose([normal.x ^ sign, normal.y ^ sign, normal.z ^ sign, cast(id)]);
    for ((o, pd), nt) in out.iter_mut().zip(h.position_depth).zip(nt) {
        *o = GPoint::from_lanes(pd, nt);
    }
}

/// f64 lanes rounded to f32.
#[inline(always)]
fn narrow(v: f64x4) -> f32x4 {
    f32x4::from(v.to_array().map(|x| x as f32))
}

/// Barycentrics clamped into the triangle: pixel centres on an edge may
/// land a rounding error outside it.
#[inline]
fn clamp_barycentrics<
    T: Copy + PartialOrd + std::ops::Add<Output = T> + std::ops::Div<Output = T>,
>(
    b1: T,
    b2: T,
    zero: T,
    one: T,
) -> (T, T) {
    let clamp = |b: T| {
        if b < zero {
            zero
        } else if b > one {
            one
        } else {
            b
        }
    };
    let (cb1, cb2) = (clamp(b1), clamp(b2));
    let s = cb1 + cb2;
    if s > one {
        (cb1 / s, cb2 / s)
    } else {
        (cb1, cb2)
    }
}

/// Vertex normals of a smooth triangle, as f32 lanes.
struct Smooth {
    /// Corner normals.
    normals: [V4f; 3],
    /// Unit winding normal (the fallback normal).
    geo: V4f,
}

impl Smooth {
    fn new(normals: [Vec3; 3], unit: Vec3) -> Self {
        Smooth {
            normals: normals.map(V4f::splat),
            geo: V4f::splat(unit),
        }
    }

    /// The unit shading normals at barycentrics `(b1, b2)` (clamped into
    /// the triangle here), interpolated in f32 where they are stored and
    /// used, and the lanes where they turn the geometric normal: a mesh
    /// whose vertex normals disagree with its winding (an inverted export)
    /// is trusted for its normals, the geometric normal turns to agree
    /// with them. [`normal_scalar`] is the same, one pixel at a time.
    #[inline(always)]
    fn normals(&self, b1: f32x4, b2: f32x4) -> (V4f, f32x4) {
        let (zero, one) = (f32x4::splat(0.0), f32x4::splat(1.0));
        let mut b1 = b1.fast_max(zero).fast_min(one);
        let mut b2 = b2.fast_max(zero).fast_min(one);
        let sum = b1 + b2;
        let over = sum.cmp_gt(one);
        if over.any() {
            b1 = over.blend(b1 / sum, b1);
            b2 = over.blend(b2 / sum, b2);
        }
        let b0 = one - b1 - b2;
        let m = self.normals[0] * b0 + self.normals[1] * b1 + self.normals[2] * b2;
        let len = m.dot(&m).sqrt();
        let usable = len.cmp_gt(zero) & len.cmp_lt(f32x4::splat(f32::INFINITY));
        let normal = V4f::select(usable, &(m * (one / len)), &self.geo);
        let turned = self.geo.dot(&normal).cmp_lt(zero);
        (normal, turned)
    }
}

/// [`Smooth::normals`] for one pixel, in scalar f32.
fn normal_scalar(corners: [Vec3; 3], unit: Vec3, b1: f32, b2: f32) -> (Vec3, bool) {
    let (b1, b2) = clamp_barycentrics(b1, b2, 0.0, 1.0);
    let b0 = 1.0 - b1 - b2;
    let m = corners[0] * b0 + corners[1] * b1 + corners[2] * b2;
    let len = m.dot(m).sqrt();
    let normal = if len > 0.0 && len < f32::INFINITY {
        m * (1.0 / len)
    } else {
        unit
    };
    (normal, unit.dot(normal) < 0.0)
}

/// Albedo of a triangle in a scene whose G-buffer keeps per-pixel albedo.
struct Albedo<'a> {
    albedo: Vec3,
    texture: Option<&'a Texture>,
    /// Corner uvs, when the mesh has them.
    uvs: Option<[DVec2; 3]>,
}

impl Albedo<'_> {
    /// At clamped barycentrics `(b1, b2)`.
    #[inline]
    fn at(&self, b1: f64, b2: f64) -> Vec3 {
        let Some(tex) = self.texture else {
            return self.albedo;
        };
        let uv = self.uvs.map_or(Vec2::ZERO, |[i, j, k]| {
            (i * (1.0 - b1 - b2) + j * b1 + k * b2).as_vec2()
        });
        self.albedo * tex.lookup_rgb(uv)
    }
}

/// A triangle's data, gathered once per run of pixels that see it, as
/// lanes.
struct RunTriangle<'a> {
    id: u32,
    /// Winding normal (unnormalised), first corner and dual vectors.
    normal: V4,
    a: V4,
    dual1: V4,
    dual2: V4,
    /// `N · (a - eye)`, the numerator of the ray parameter.
    numerator: f64x4,
    /// Depth of the centroid, for grazing rays.
    centroid_t: f64x4,
    /// All ones where the eye is behind the winding normal
    /// (`numerator > 0`), in front of it (`numerator < 0`); neither when it
    /// lies in the plane.
    back: f32x4,
    front: f32x4,
    /// The stored normal and id lane of a flat triangle.
    flat: f32x4,
    smooth: Option<Smooth>,
    /// Only for G-buffers that keep albedo.
    albedo: Option<Albedo<'a>>,
}

impl<'a> RunTriangle<'a> {
    fn new(ctx: &Ctx<'a>, id: u32, textured: bool) -> Self {
        let (scene, geometry, view) = (ctx.scene, ctx.geometry, ctx.view);
        let t = id as usize;
        let f = &geometry.frames[t];
        let numerator = f.normal.dot(f.a - view.eye);
        let (o, local) = geometry.locate(id);
        let mesh = &scene.objects[o].mesh;
        let corners = mesh.triangles[local];
        let unit = geometry.unit_normals[t];
        let mask = |b: bool| f32x4::splat(if b { f32::from_bits(u32::MAX) } else { 0.0 });
        let mut r = RunTriangle {
            id,
            normal: V4::splat(f.normal),
            a: V4::splat(f.a),
            dual1: V4::splat(f.dual1),
            dual2: V4::splat(f.dual2),
            numerator: f64x4::splat(numerator),
            centroid_t: f64x4::splat((f.centroid - view.eye).dot(view.forward)),
            back: mask(numerator > 0.0),
            front: mask(numerator < 0.0),
            flat: f32x4::ZERO,
            smooth: mesh
                .normals
                .as_ref()
                .map(|ns| Smooth::new(corners.map(|i| ns[i as usize]), unit)),
            albedo: textured.then(|| {
                let m = &scene.materials[geometry.triangle_material[t] as usize];
                Albedo {
                    albedo: m.albedo,
                    texture: m.albedo_texture.and_then(|i| scene.textures.get(i)),
                    uvs: mesh
                        .uvs
                        .as_ref()
                        .map(|uv| corners.map(|i| uv[i as usize].as_dvec2())),
                }
            }),
        };
        r.flat = r.facing(unit, false);
        r
    }

    /// The stored normal-and-id lane of a pixel whose unit shading normal
    /// is `normal`, `turned` when the vertex normals turned the geometric
    /// normal against the winding. Two-sided surfaces: both normals face
    /// the viewer, which is a property of the plane (the side of it the
    /// eye is on), not of the pixel.
    fn facing(&self, normal: Vec3, turned: bool) -> f32x4 {
        let (back, front) = (self.back.move_mask() != 0, self.front.move_mask() != 0);
        let away = if turned { front } else { back };
        let normal = if away { -normal } else { normal };
        let flag = if turned != away { GEO_FLIPPED } else { 0 };
        f32x4::from([normal.x, normal.y, normal.z, f32::from_bits(self.id | flag)])
    }
}

/// The scalar twin of [`resolve`]: one pixel at a time through the same
/// formulas (the ray from [`View::primary_ray_unnormalized`], the frame
/// rebuilt from the corners). Kept to test the lanes against.
pub fn resolve_scalar(
    scene: &Scene,
    geometry: &SceneGeometry,
    view: &View,
    ids: &TiledTarget<u32>,
) -> Result<GBuffer> {
    let mut g = GBuffer::blank(view);
    g.bind(scene, geometry)?;
    let textured = !g.albedo.is_empty();
    let (w, h) = (view.width, view.height);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let id = ids.get(x, y);
            if id == NO_TRIANGLE {
                continue;
            }
            let corners =
                geometry.triangles[id as usize].map(|v| geometry.positions[v as usize].as_dvec3());
            let frame = TriangleFrame::new(corners);
            let dir = view.primary_ray_unnormalized(x, y);
            let (t, b1, b2) = frame.hit(view.eye, dir).unwrap_or((
                (frame.centroid - view.eye).dot(view.forward),
                1.0 / 3.0,
                1.0 / 3.0,
            ));
            // `dir` has unit length along `forward`, so `t` is the view
            // depth itself.
            let position = view.eye + dir * t;
            let numerator = frame.normal.dot(frame.a - view.eye);
            let unit = frame.normal.normalize_or_zero().as_vec3();
            let (o, local) = geometry.locate(id);
            let mesh = &scene.objects[o].mesh;
            let (normal, turned) = match &mesh.normals {
                Some(ns) => normal_scalar(
                    mesh.triangles[local].map(|v| ns[v as usize]),
                    unit,
                    b1 as f32,
                    b2 as f32,
                ),
                None => (unit, false),
            };
            let away = if turned {
                numerator < 0.0
            } else {
                numerator > 0.0
            };
            g.points[i] = GPoint {
                position: position.as_vec3(),
                depth: t as f32,
                normal: if away { -normal } else { normal },
                triangle: id | if turned != away { GEO_FLIPPED } else { 0 },
            };
            if textured {
                let m = &scene.materials[geometry.triangle_material[id as usize] as usize];
                let (cb1, cb2) = clamp_barycentrics(b1, b2, 0.0, 1.0);
                let uv = interpolate_uv(scene, geometry, id, cb1, cb2);
                g.albedo[i] = match m.albedo_texture.and_then(|t| scene.textures.get(t)) {
                    Some(tex) => m.albedo * tex.lookup_rgb(uv),
                    None => m.albedo,
                };
            }
        }
    }
    Ok(g)
}

/// Four 3-vectors in structure-of-arrays form.
#[derive(Clone, Copy)]
struct V4 {
    x: f64x4,
    y: f64x4,
    z: f64x4,
}

impl V4 {
    #[inline(always)]
    fn splat(v: DVec3) -> Self {
        V4 {
            x: f64x4::splat(v.x),
            y: f64x4::splat(v.y),
            z: f64x4::splat(v.z),
        }
    }

    #[inline(always)]
    fn dot(&self, o: &V4) -> f64x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
}

impl std::ops::Add for V4 {
    type Output = V4;
    #[inline(always)]
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
    #[inline(always)]
    fn sub(self, o: V4) -> V4 {
        V4 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }
}

impl std::ops::Mul<f64x4> for V4 {
    type Output = V4;
    #[inline(always)]
    fn mul(self, s: f64x4) -> V4 {
        V4 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }
}

/// Four f32 3-vectors in structure-of-arrays form.
#[derive(Clone, Copy)]
struct V4f {
    x: f32x4,
    y: f32x4,
    z: f32x4,
}

impl V4f {
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        V4f {
            x: f32x4::splat(v.x),
            y: f32x4::splat(v.y),
            z: f32x4::splat(v.z),
        }
    }

    #[inline(always)]
    fn dot(&self, o: &V4f) -> f32x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    fn select(mask: f32x4, a: &V4f, b: &V4f) -> V4f {
        V4f {
            x: mask.blend(a.x, b.x),
            y: mask.blend(a.y, b.y),
            z: mask.blend(a.z, b.z),
        }
    }
}

impl std::ops::Add for V4f {
    type Output = V4f;
    #[inline(always)]
    fn add(self, o: V4f) -> V4f {
        V4f {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }
}

impl std::ops::Mul<f32x4> for V4f {
    type Output = V4f;
    #[inline(always)]
    fn mul(self, s: f32x4) -> V4f {
        V4f {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }
}
