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
use crate::simd::{f32x4, f64x4, i32x4, u32x4};
use crate::view::View;
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;

/// Pixels per lane group.
const LANES: usize = 4;

/// Image rows per parallel task (a divisor of the tile size).
const BAND: usize = 32;

/// Prepared triangles a band keeps.
const CACHE: usize = 128;

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
    let task = w * BAND;
    let band = |(c, (points, albedo)): (usize, (&mut [GPoint], &mut [Vec3]))| {
        ctx.band(ids, c * BAND, points, albedo);
    };
    if gbuffer.albedo.is_empty() {
        gbuffer
            .points
            .par_chunks_mut(task)
            .map(|p| (p, &mut [][..]))
            .enumerate()
            .for_each(band);
    } else {
        gbuffer
            .points
            .par_chunks_mut(task)
            .zip(gbuffer.albedo.par_chunks_mut(task))
            .enumerate()
            .for_each(band);
    }
}

/// What every band of one resolve shares.
struct Ctx<'a> {
    scene: &'a Scene,
    geometry: &'a SceneGeometry,
    view: &'a View,
    columns: &'a Columns,
}

impl<'a> Ctx<'a> {
    /// Resolves the band of rows from `y0` into `points` (whole rows) and
    /// `albedo` (the same rows when the G-buffer keeps albedo, else
    /// empty). Tile by tile, row by row inside a tile, so a triangle seen
    /// in several rows is prepared once.
    fn band(&self, ids: &TiledTarget<u32>, y0: usize, points: &mut [GPoint], albedo: &mut [Vec3]) {
        let view = self.view;
        let w = view.width as usize;
        let rows = points.len() / w;
        let h = view.height as f64;
        let dirs: [DVec3; BAND] = std::array::from_fn(|r| {
            let ys = (1.0 - 2.0 * ((y0 + r) as f64 + 0.5) / h) * view.tan_half_fov;
            view.forward + ys * view.up
        });
        let eye = V4::splat(view.eye);
        let textured = !albedo.is_empty();
        let grid = ids.grid();
        let (ty, ly0) = (y0 / TILE_SIZE, y0 % TILE_SIZE);
        let mut cache = RunCache::new();
        for tx in 0..grid.tiles_x {
            let tile = ids.tile(ty * grid.tiles_x + tx);
            let x0 = tx * TILE_SIZE;
            let n = TILE_SIZE.min(w - x0);
            for (r, &row) in dirs.iter().enumerate().take(rows) {
                let row4 = V4::splat(row);
                let seg = &tile[(ly0 + r) * TILE_SIZE..][..TILE_SIZE];
                // The rest of the image row: a group may write all its
                // lanes past its run's end; the pixels there belong to
                // runs (or tiles) resolved later, which overwrite them.
                let out = &mut points[r * w + x0..(r + 1) * w];
                let albedo = if textured {
                    &mut albedo[r * w + x0..][..n]
                } else {
                    &mut [][..]
                };
                let mut starts = run_starts(seg, n);
                while starts != 0 {
                    let i = starts.trailing_zeros() as usize;
                    starts &= starts - 1;
                    let j = if starts == 0 {
                        n
                    } else {
                        starts.trailing_zeros() as usize
                    };
                    let tri = seg[i];
                    if tri == NO_TRIANGLE {
                        out[i..j].fill(GPoint::BACKGROUND);
                        continue;
                    }
                    let t = cache.get(self, tri, textured);
                    let mut x = i;
                    while x < j {
                        let end = (x + LANES).min(j);
                        if end == x + 1 && !textured {
                            // One pixel (a third of all runs are one
                            // pixel long): the same arithmetic without
                            // lanes.
                            self.single(t, row, x0 + x, &mut out[x]);
                            x = end;
                            continue;
                        }
                        let lanes = Lanes {
                            dir: row4 + self.columns.lanes(x0 + x),
                            eye,
                        };
                        let lanes_end = if x + LANES <= out.len() && !textured {
                            x + LANES
                        } else {
                            end
                        };
                        let out = &mut out[x..lanes_end];
                        if textured {
                            lanes.textured(t, &t.frame, out, &mut albedo[x..end]);
                        } else if t.smooth {
                            lanes.smooth(t, out);
                        } else {
                            lanes.flat(t, out);
                        }
                        x = end;
                    }
                }
            }
        }
    }
}

impl<'a> Ctx<'a> {
    /// One pixel at column `x` of the row whose rays are `row + right
    /// xs`: [`Lanes`]' arithmetic in scalars, operation for operation, so
    /// the bits are those a lane would give.
    #[inline]
    fn single(&self, r: &RunTriangle, row: DVec3, x: usize, out: &mut GPoint) {
        let view = self.view;
        let f = &r.frame;
        let c = self.columns;
        let dir = DVec3::new(row.x + c.x[x], row.y + c.y[x], row.z + c.z[x]);
        let numerator = r.numerator.to_array()[0];
        let t = numerator / f.normal.dot(dir);
        let hit = view.eye + dir * t;
        let ok = t > 0.0 && t < f64::INFINITY;
        let (t, position) = if ok {
            (t, hit)
        } else {
            let t = r.centroid_t.to_array()[0];
            (t, view.eye + dir * t)
        };
        let position_depth = f32x4::from([
            position.x as f32,
            position.y as f32,
            position.z as f32,
            t as f32,
        ]);
        let normal_triangle = if r.smooth {
            let (b1, b2) = if ok {
                let d = (hit - f.a).as_vec3();
                (d.dot(r.duals[0]), d.dot(r.duals[1]))
            } else {
                (1.0 / 3.0, 1.0 / 3.0)
            };
            let (normal, turned) = normal_scalar(r.corners, r.unit, b1, b2);
            r.lane(normal, turned)
        } else {
            r.flat
        };
        *out = GPoint::from_lanes(position_depth, normal_triangle);
    }
}

/// Bit `k` set where a run of equal ids starts in `seg[..n]` (`k = 0` or
/// `seg[k] != seg[k - 1]`); `seg` is a whole tile row.
#[inline]
fn run_starts(seg: &[u32], n: usize) -> u64 {
    let load = |k: usize| -> i32x4 {
        let a: [u32; 4] = seg[k..k + 4].try_into().expect("tile row of 64");
        i32x4::from(a.map(|v| v as i32))
    };
    let mut same = 0u64;
    // Lane k of chunk c compares seg[4c + k] with seg[4c + k - 1].
    let first = load(0);
    let shifted: [u32; 4] = [!seg[0], seg[0], seg[1], seg[2]];
    same |= first
        .cmp_eq(i32x4::from(shifted.map(|v| v as i32)))
        .move_mask() as u64
        & 0xf;
    for c in 1..TILE_SIZE / 4 {
        let eq = load(4 * c).cmp_eq(load(4 * c - 1)).move_mask() as u64 & 0xf;
        same |= eq << (4 * c);
    }
    let live = if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
    !same & live
}

/// Triangles prepared for this band, by id modulo the size.
struct RunCache<'a> {
    slots: [RunTriangle<'a>; CACHE],
}

impl<'a> RunCache<'a> {
    fn new() -> Self {
        RunCache {
            slots: [RunTriangle::EMPTY; CACHE],
        }
    }

    /// Triangle `id`, prepared now unless it is cached.
    #[inline]
    fn get(&mut self, ctx: &Ctx<'a>, id: u32, textured: bool) -> &RunTriangle<'a> {
        let slot = &mut self.slots[id as usize % CACHE];
        if slot.id != id {
            slot.load(ctx, id, textured);
        }
        slot
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
        store(out, h.position_depth, [r.flat; LANES]);
    }

    /// Barycentrics of the hits for the shading normals: the offsets from
    /// the first corner in f64 (where they cancel), rounded to f32 (their
    /// size is the triangle's), dotted with the duals in f32; grazing
    /// lanes at the centroid.
    #[inline(always)]
    fn barycentrics_f32(&self, r: &RunTriangle, h: &Hits) -> (f32x4, f32x4) {
        let d = h.hit - r.a;
        let d = V4f {
            x: narrow(d.x),
            y: narrow(d.y),
            z: narrow(d.z),
        };
        let (b1, b2) = (d.dot(&r.dual1f), d.dot(&r.dual2f));
        if h.all_ok {
            (b1, b2)
        } else {
            let ok = h.ok.move_mask();
            let third = 1.0 / 3.0;
            let pick = |b: f32x4| {
                let b = b.to_array();
                f32x4::from(std::array::from_fn::<f32, LANES, _>(|k| {
                    if ok >> k & 1 != 0 {
                        b[k]
                    } else {
                        third
                    }
                }))
            };
            (pick(b1), pick(b2))
        }
    }

    /// Barycentrics of the hits in f64 (for texture coordinates), grazing
    /// lanes at the centroid.
    #[inline(always)]
    fn barycentrics(&self, r: &RunTriangle, f: &TriangleFrame, h: &Hits) -> (f64x4, f64x4) {
        let d = h.hit - r.a;
        let (b1, b2) = (d.dot(&V4::splat(f.dual1)), d.dot(&V4::splat(f.dual2)));
        if h.all_ok {
            (b1, b2)
        } else {
            let third = f64x4::splat(1.0 / 3.0);
            (h.ok.blend(b1, third), h.ok.blend(b2, third))
        }
    }

    /// A triangle with vertex normals.
    #[inline(always)]
    fn smooth(&self, r: &RunTriangle, out: &mut [GPoint]) {
        let h = self.hits(r);
        let (b1, b2) = self.barycentrics_f32(r, &h);
        store(out, h.position_depth, normal_lanes(r, b1, b2));
    }

    /// A scene with albedo textures: as [`Lanes::smooth`] or
    /// [`Lanes::flat`], and the albedo per lane from f64 uvs.
    fn textured(
        &self,
        r: &RunTriangle,
        f: &TriangleFrame,
        out: &mut [GPoint],
        albedo: &mut [Vec3],
    ) {
        let h = self.hits(r);
        let nt = if r.smooth {
            let (b1, b2) = self.barycentrics_f32(r, &h);
            normal_lanes(r, b1, b2)
        } else {
            [r.flat; LANES]
        };
        store(out, h.position_depth, nt);
        let (b1, b2) = self.barycentrics(r, f, &h);
        let (b1, b2) = (b1.to_array(), b2.to_array());
        for (k, a) in albedo.iter_mut().enumerate() {
            let (cb1, cb2) = clamp_barycentrics(b1[k], b2[k], 0.0, 1.0);
            *a = r.albedo.as_ref().map_or(Vec3::ZERO, |al| al.at(cb1, cb2));
        }
    }
}

/// Writes the first `out.len()` (at most [`LANES`]) lanes.
#[inline(always)]
fn store(out: &mut [GPoint], position_depth: [f32x4; LANES], normal_triangle: [f32x4; LANES]) {
    if let Ok(out) = <&mut [GPoint; LANES]>::try_from(&mut *out) {
        for k in 0..LANES {
            out[k] = GPoint::from_lanes(position_depth[k], normal_triangle[k]);
        }
    } else {
        for (k, o) in out.iter_mut().enumerate() {
            *o = GPoint::from_lanes(position_depth[k], normal_triangle[k]);
        }
    }
}

/// The `[normal, triangle bits]` lanes of a smooth triangle: shading
/// normals facing the viewer, ids with their geometric-normal flags.
#[inline(always)]
fn normal_lanes(r: &RunTriangle, b1: f32x4, b2: f32x4) -> [f32x4; LANES] {
    let (normal, turned) = r.normals(b1, b2);
    let (sign, id) = match turned {
        // Vertex normals that agree with the winding never turn it: the
        // run's facing.
        None => (r.sign, r.flat.to_array()[3]),
        Some(turned) => {
            let away = turned.blend(r.front, r.back);
            let flag = u32x4::splat(GEO_FLIPPED).cast_f32();
            let id = u32x4::splat(r.id) | ((turned ^ away) & flag).cast_u32();
            let id = id.cast_f32();
            return f32x4::transpose([
                normal.x ^ (away & f32x4::splat(-0.0)),
                normal.y ^ (away & f32x4::splat(-0.0)),
                normal.z ^ (away & f32x4::splat(-0.0)),
                id,
            ]);
        }
    };
    f32x4::transpose([
        normal.x ^ sign,
        normal.y ^ sign,
        normal.z ^ sign,
        f32x4::splat(id),
    ])
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

/// Vertex normals whose dot products with the stored unit winding normal
/// (f32) are all at least this agree with the winding: an interpolated
/// normal, a convex combination of them (clamped barycentrics, unit
/// length at most), then has a dot product of at least about this much,
/// some 10^4 times the f32 rounding of the interpolation, normalisation
/// and dot product, and never turns the geometric normal.
const AGREE: f32 = 1e-3;

/// [`RunTriangle::normals`] for one pixel, in scalar f32.
fn normal_scalar(corners: [Vec3; 3], unit: Vec3, b1: f32, b2: f32) -> (Vec3, bool) {
    let (b1, b2) = clamp_barycentrics(b1, b2, 0.0, 1.0);
    let [n0, n1, n2] = corners;
    let m = n0 + (n1 - n0) * b1 + (n2 - n0) * b2;
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

/// A triangle's data for the lanes, prepared once per band that sees it.
struct RunTriangle<'a> {
    id: u32,
    /// The triangle's f64 frame ([`SceneGeometry::frame`]).
    frame: TriangleFrame,
    /// Winding normal (unnormalised) and first corner.
    normal: V4,
    a: V4,
    /// The duals in f32, as lanes and as scalars.
    dual1f: V4f,
    dual2f: V4f,
    duals: [Vec3; 2],
    /// `N · (a - eye)`, the numerator of the ray parameter.
    numerator: f64x4,
    /// Depth of the centroid, for grazing rays.
    centroid_t: f64x4,
    /// All ones where the eye is behind the winding normal
    /// (`numerator > 0`), in front of it (`numerator < 0`); neither when it
    /// lies in the plane.
    back: f32x4,
    front: f32x4,
    /// Sign bits of an unturned normal facing the viewer (`back`'s).
    sign: f32x4,
    /// The stored `[normal, triangle bits]` of a flat triangle, facing the
    /// viewer (the triangle bits also those of an unturned smooth one).
    flat: f32x4,
    /// Whether the mesh has vertex normals: `n0`, `n1 - n0`, `n2 - n0`.
    smooth: bool,
    n0: V4f,
    e1: V4f,
    e2: V4f,
    /// Unit winding normal (the fallback shading normal).
    geo: V4f,
    /// The same, and the corner normals, as scalars.
    unit: Vec3,
    corners: [Vec3; 3],
    /// The vertex normals agree with the winding ([`AGREE`]).
    agree: bool,
    /// Only for G-buffers that keep albedo.
    albedo: Option<Albedo<'a>>,
}

impl<'a> RunTriangle<'a> {
    /// An empty cache slot.
    const EMPTY: RunTriangle<'a> = RunTriangle {
        id: NO_TRIANGLE,
        frame: TriangleFrame::ZERO,
        normal: V4::ZERO,
        a: V4::ZERO,
        dual1f: V4f::ZERO,
        dual2f: V4f::ZERO,
        duals: [Vec3::ZERO; 2],
        numerator: f64x4::ZERO,
        centroid_t: f64x4::ZERO,
        back: f32x4::ZERO,
        front: f32x4::ZERO,
        sign: f32x4::ZERO,
        flat: f32x4::ZERO,
        smooth: false,
        n0: V4f::ZERO,
        e1: V4f::ZERO,
        e2: V4f::ZERO,
        geo: V4f::ZERO,
        unit: Vec3::ZERO,
        corners: [Vec3::ZERO; 3],
        agree: false,
        albedo: None,
    };

    /// Prepares triangle `id` in place.
    fn load(&mut self, ctx: &Ctx<'a>, id: u32, textured: bool) {
        let (scene, geometry, view) = (ctx.scene, ctx.geometry, ctx.view);
        let t = id as usize;
        let f = &geometry.frame(id);
        let numerator = f.normal.dot(f.a - view.eye);
        let (back, front) = (numerator > 0.0, numerator < 0.0);
        let unit = geometry.unit_normals[t];
        let mask = |b: bool| f32x4::splat(if b { f32::from_bits(u32::MAX) } else { 0.0 });
        self.id = id;
        self.frame = *f;
        self.normal = V4::splat(f.normal);
        self.a = V4::splat(f.a);
        self.duals = [f.dual1.as_vec3(), f.dual2.as_vec3()];
        self.dual1f = V4f::splat(self.duals[0]);
        self.dual2f = V4f::splat(self.duals[1]);
        self.numerator = f64x4::splat(numerator);
        self.centroid_t = f64x4::splat((f.centroid - view.eye).dot(view.forward));
        self.back = mask(back);
        self.front = mask(front);
        self.sign = mask(back) & f32x4::splat(-0.0);
        self.flat = self.lane(unit, false);
        let (o, local) = geometry.locate(id);
        let mesh = &scene.objects[o].mesh;
        let corners = mesh.triangles[local];
        self.smooth = false;
        if let Some(ns) = &mesh.normals {
            let [n0, n1, n2] = corners.map(|i| ns[i as usize]);
            if n0 == n1 && n1 == n2 {
                // Equal vertex normals (the faces of boxes and quads): the
                // differences are zeros, so every pixel interpolates `n0`
                // exactly (barycentrics are clamped to +0 or more) and gets
                // the normal of barycentrics (0, 0). The run's, then.
                let (normal, turned) = normal_scalar([n0, n1, n2], unit, 0.0, 0.0);
                self.flat = self.lane(normal, turned);
                self.corners = [n0, n1, n2];
                self.unit = unit;
                return self.load_albedo(ctx, t, corners, textured);
            }
            self.smooth = true;
            self.n0 = V4f::splat(n0);
            self.e1 = V4f::splat(n1 - n0);
            self.e2 = V4f::splat(n2 - n0);
            self.geo = V4f::splat(unit);
            self.unit = unit;
            self.corners = [n0, n1, n2];
            self.agree = [n0, n1, n2].iter().all(|n| unit.dot(*n) >= AGREE);
        }
        self.load_albedo(ctx, t, corners, textured);
    }

    /// The albedo part of [`RunTriangle::load`].
    fn load_albedo(&mut self, ctx: &Ctx<'a>, t: usize, corners: [u32; 3], textured: bool) {
        let (scene, geometry) = (ctx.scene, ctx.geometry);
        let mesh = &scene.objects[geometry.triangle_object[t] as usize].mesh;
        self.albedo = textured.then(|| {
            let m = &scene.materials[geometry.triangle_material[t] as usize];
            Albedo {
                albedo: m.albedo,
                texture: m.albedo_texture.and_then(|i| scene.textures.get(i)),
                uvs: mesh
                    .uvs
                    .as_ref()
                    .map(|uv| corners.map(|i| uv[i as usize].as_dvec2())),
            }
        });
    }

    /// The stored `[normal, triangle bits]` lane of a pixel whose unit
    /// shading normal is `normal`, `turned` when it turns the geometric
    /// normal against the winding. Two-sided surfaces: both normals face
    /// the viewer, which is a property of the plane (the side of it the
    /// eye is on), not of the pixel.
    fn lane(&self, normal: Vec3, turned: bool) -> f32x4 {
        let (back, front) = (self.back.move_mask() != 0, self.front.move_mask() != 0);
        let away = if turned { front } else { back };
        let normal = if away { -normal } else { normal };
        let flag = if turned != away { GEO_FLIPPED } else { 0 };
        f32x4::from([normal.x, normal.y, normal.z, f32::from_bits(self.id | flag)])
    }

    /// The unit shading normals at barycentrics `(b1, b2)` (clamped into
    /// the triangle here), interpolated in f32 where they are stored and
    /// used, and the lanes where they turn the geometric normal (`None`:
    /// none can, see [`AGREE`]): a mesh whose vertex normals disagree with
    /// its winding (an inverted export) is trusted for its normals, the
    /// geometric normal turns to agree with them. [`normal_scalar`] is the
    /// same, one pixel at a time.
    #[inline(always)]
    fn normals(&self, b1: f32x4, b2: f32x4) -> (V4f, Option<f32x4>) {
        let (zero, one) = (f32x4::splat(0.0), f32x4::splat(1.0));
        let mut b1 = b1.max(zero).min(one);
        let mut b2 = b2.max(zero).min(one);
        let sum = b1 + b2;
        let over = sum.cmp_gt(one);
        if over.any() {
            b1 = over.blend(b1 / sum, b1);
            b2 = over.blend(b2 / sum, b2);
        }
        let m = self.n0 + self.e1 * b1 + self.e2 * b2;
        let len = m.dot(&m).sqrt();
        let usable = len.cmp_gt(zero) & len.cmp_lt(f32x4::splat(f32::INFINITY));
        let mut normal = m * (one / len);
        if usable.move_mask() != 0b1111 {
            normal = V4f::select(usable, &normal, &self.geo);
        }
        if self.agree {
            return (normal, None);
        }
        (normal, Some(self.geo.dot(&normal).cmp_lt(zero)))
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
            let hit = frame.hit(view.eye, dir);
            let t = hit.map_or((frame.centroid - view.eye).dot(view.forward), |h| h.0);
            // `dir` has unit length along `forward`, so `t` is the view
            // depth itself.
            let position = view.eye + dir * t;
            // Barycentrics for the normals: the offset in f64, rounded,
            // dotted in f32 (as the lanes do); f64 ones for uvs.
            let (b1, b2) = hit.map_or((1.0 / 3.0, 1.0 / 3.0), |_| {
                let d = (position - frame.a).as_vec3();
                (d.dot(frame.dual1.as_vec3()), d.dot(frame.dual2.as_vec3()))
            });
            let (b1_64, b2_64) = hit.map_or((1.0 / 3.0, 1.0 / 3.0), |h| (h.1, h.2));
            let numerator = frame.normal.dot(frame.a - view.eye);
            let unit = frame.normal.normalize_or_zero().as_vec3();
            let (o, local) = geometry.locate(id);
            let mesh = &scene.objects[o].mesh;
            let (normal, turned) = match &mesh.normals {
                Some(ns) => {
                    normal_scalar(mesh.triangles[local].map(|v| ns[v as usize]), unit, b1, b2)
                }
                None => (unit, false),
            };
            let away = if turned {
                numerator < 0.0
            } else {
                numerator > 0.0
            };
            g.points[i] = GPoint::new(
                position.as_vec3(),
                t as f32,
                if away { -normal } else { normal },
                id | if turned != away { GEO_FLIPPED } else { 0 },
            );
            if textured {
                let m = &scene.materials[geometry.triangle_material[id as usize] as usize];
                let (cb1, cb2) = clamp_barycentrics(b1_64, b2_64, 0.0, 1.0);
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
    const ZERO: V4 = V4 {
        x: f64x4::ZERO,
        y: f64x4::ZERO,
        z: f64x4::ZERO,
    };

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
    const ZERO: V4f = V4f {
        x: f32x4::ZERO,
        y: f32x4::ZERO,
        z: f32x4::ZERO,
    };

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
