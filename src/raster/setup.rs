//! Triangle setup: projection to fixed-point screen coordinates, exact
//! integer edge functions with the top-left fill rule, bounding boxes and
//! interpolation planes.
//!
//! Screen space has its origin at the top-left corner of the image, `x` to
//! the right and `y` down; pixel `(i, j)` is sampled at its centre
//! `(i + 0.5, j + 0.5)`. Vertices snap to 1/256 pixel (8 sub-pixel bits).
//! Edge functions are evaluated exactly in `i64` (products of two
//! coordinates of at most 2^26 sub-pixels stay below 2^53, so their `f64`
//! images in the SIMD inner loop are exact too): two triangles sharing an
//! edge compute exactly negated edge values, and the top-left rule gives
//! every sample on the edge to exactly one of them. That is watertightness.

use super::clip::MAX_CLIPPED_VERTICES;
use super::simd::LANE_OFFSETS;
use super::vertex::ClipVertex;
use crate::simd::f32x8;

/// Sub-pixel precision of snapped vertices, in bits.
pub const SUBPIXEL_BITS: u32 = 8;
/// Sub-pixel units per pixel.
pub const SUBPIXEL: i64 = 1 << SUBPIXEL_BITS;
const HALF_PIXEL: i64 = SUBPIXEL / 2;

/// Pixels of guard band around the screen. Triangles reaching further are
/// clipped; inside it, the scissor (clamped bounding boxes) does the work.
/// `(16384 + 2 * GUARD_BAND) * 256 < 2^25` keeps edge products exact.
pub const GUARD_BAND: i64 = 8192;

/// Largest image side the rasterizer accepts.
pub const MAX_SIDE: u32 = 16384;

/// An edge function `E(X, Y) = a X + b Y + c` over sub-pixel sample
/// coordinates, with the top-left bias folded into `c`: a sample is inside
/// the edge iff `E >= 0`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeFunction {
    /// Coefficient of X.
    pub a: i64,
    /// Coefficient of Y.
    pub b: i64,
    /// Constant, including the fill-rule bias.
    pub c: i64,
}

impl EdgeFunction {
    /// Edge from `p` to `q` of a triangle with positive orientation.
    pub(crate) fn new(p: (i64, i64), q: (i64, i64)) -> Self {
        let a = p.1 - q.1;
        let b = q.0 - p.0;
        // Top edge (horizontal, interior below) or left edge (going up):
        // samples exactly on them are inside; on other edges, outside.
        let top_left = a > 0 || (a == 0 && b > 0);
        let c = -(a * p.0 + b * p.1) - i64::from(!top_left);
        EdgeFunction { a, b, c }
    }

    /// Value at the centre of pixel `(x, y)`.
    #[inline]
    pub fn at_pixel(&self, x: i64, y: i64) -> i64 {
        self.a * (x * SUBPIXEL + HALF_PIXEL) + self.b * (y * SUBPIXEL + HALF_PIXEL) + self.c
    }

    /// Change of the value from one pixel to the next along x.
    #[inline]
    pub fn step_x(&self) -> i64 {
        self.a * SUBPIXEL
    }

    /// Change of the value from one pixel to the next along y.
    #[inline]
    pub fn step_y(&self) -> i64 {
        self.b * SUBPIXEL
    }
}

/// A quantity interpolated linearly in screen space:
/// `value(x, y) = v0 + dx (x - x0) + dy (y - y0)` at pixel centres.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Plane {
    /// Reference point x (pixels, screen space).
    pub x0: f32,
    /// Reference point y.
    pub y0: f32,
    /// Value at the reference point.
    pub v0: f32,
    /// Derivative along x.
    pub dx: f32,
    /// Derivative along y.
    pub dy: f32,
}

impl Plane {
    /// Plane through three screen points `(x, y, value)` (f64 for the
    /// solve; the triangle is non-degenerate here).
    fn through(p: [(f64, f64, f64); 3]) -> Self {
        let (x0, y0, v0) = p[0];
        let (x1, y1, v1) = (p[1].0 - x0, p[1].1 - y0, p[1].2 - v0);
        let (x2, y2, v2) = (p[2].0 - x0, p[2].1 - y0, p[2].2 - v0);
        let det = x1 * y2 - x2 * y1;
        Plane {
            x0: x0 as f32,
            y0: y0 as f32,
            v0: v0 as f32,
            dx: ((v1 * y2 - v2 * y1) / det) as f32,
            dy: ((v2 * x1 - v1 * x2) / det) as f32,
        }
    }

    /// Values at the centres of pixels `(x + k, y)`, k = 0..8. Each lane is
    /// computed from its own pixel coordinates, so a pixel's value does not
    /// depend on where a batch of lanes starts.
    #[inline]
    pub fn lanes(&self, x: i32, y: i32) -> f32x8 {
        self.lanes_on_row(self.row_base(y), x)
    }

    /// Lane 0 of [`Plane::lanes`] at `(x, y)`, computed by the same
    /// operations: the value the SIMD path gives pixel `(x, y)`.
    #[inline]
    pub fn at(&self, x: i32, y: i32) -> f32 {
        let cx = (x as f32 + 0.0) + 0.5 - self.x0;
        self.row_base(y) + self.dx * cx
    }

    /// The part of [`Plane::lanes`] that is constant along row `y`.
    #[inline]
    pub fn row_base(&self, y: i32) -> f32 {
        let cy = y as f32 + 0.5 - self.y0;
        self.v0 + self.dy * cy
    }

    /// [`Plane::lanes`] from the row's [`Plane::row_base`]: the same
    /// operations in the same order, so the same bits.
    #[inline]
    pub fn lanes_on_row(&self, base: f32, x: i32) -> f32x8 {
        let cx =
            (f32x8::splat(x as f32) + LANE_OFFSETS) + f32x8::splat(0.5) - f32x8::splat(self.x0);
        f32x8::splat(base) + f32x8::splat(self.dx) * cx
    }
}

/// A triangle ready for tile traversal.
#[derive(Debug, Clone, Copy)]
pub struct SetupTriangle<const N: usize> {
    /// The three edge functions, inside where all are >= 0.
    pub edges: [EdgeFunction; 3],
    /// Covered pixel range, inclusive: `[x0, x1] × [y0, y1]`, clamped to the
    /// screen.
    pub bbox: [i32; 4],
    /// Depth `z / w` (reversed Z: 1 at the near plane, 0 at infinity).
    pub depth: Plane,
    /// `1 / w`, for perspective correction.
    pub inv_w: Plane,
    /// `varying / w` for each varying.
    pub varyings: [Plane; N],
    /// Counter-clockwise in the world, seen from the camera.
    pub front_facing: bool,
    /// Index of the input triangle it came from.
    pub primitive: u32,
    /// The snapped triangle spans less than 8 pixels in x and in y: its
    /// edge values over its box fit `i32` (see the tile traversal).
    pub small: bool,
    /// Every edge has `|a| + |b| < 2^19` sub-pixels: over an 8×8 block an
    /// edge crosses, its values differ by at most `7 · 256 · 2^19 < 2^31`,
    /// so they fit `i32` lanes exactly.
    pub block_i32: bool,
    /// [`NO_QUAD`], or the index of the [`QuadExtra`] that makes this a
    /// merged pair of triangles (counting passes only).
    pub quad: u32,
}

/// [`SetupTriangle::quad`] of a plain triangle.
pub const NO_QUAD: u32 = u32::MAX;

/// The rest of a merged quad: two triangles `(v0, v1, v2)`, `(v0, v2, v3)`
/// of the same facing whose union is a strictly convex quadrilateral. Its
/// coverage is the pixels inside all four outer edges: the top-left rule
/// decides a pixel centre on an edge as if it were moved by an
/// infinitesimal `(ε, ε²)`, so a pixel is in a triangle iff that moved
/// point is in its interior, and the open quad minus the diagonal is the
/// union of the open triangles. Each covered pixel takes the depth of the
/// triangle that would have covered it (the first one's diagonal edge
/// decides, exactly), so drawing the quad gives the bits drawing the two
/// triangles gives.
#[derive(Debug, Clone, Copy)]
pub struct QuadExtra {
    /// The outer edge the [`SetupTriangle`]'s three edges leave out.
    pub edge: EdgeFunction,
    /// The first triangle's edge along the diagonal: pixels where it is
    /// `>= 0` belong to the first triangle.
    pub diagonal: EdgeFunction,
    /// The second triangle's depth plane.
    pub depth2: Plane,
}

/// Screen dimensions and guard band for setup.
#[derive(Debug, Clone, Copy)]
pub struct Viewport {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Viewport {
    /// Guard band extents in NDC units, for the clipper.
    pub fn guard_ndc(&self) -> (f32, f32) {
        let gx = 1.0 + 2.0 * GUARD_BAND as f64 / self.width as f64;
        let gy = 1.0 + 2.0 * GUARD_BAND as f64 / self.height as f64;
        // Round inward so that a vertex on the clip plane stays inside the
        // fixed-point range.
        (gx as f32 * (1.0 - 1e-6), gy as f32 * (1.0 - 1e-6))
    }
}

/// Rounds a screen coordinate (pixels) to the nearest sub-pixel, halves
/// away from -infinity. Done by truncating a shifted positive value: `as`
/// conversion is one instruction on every x86-64 level, `f64::round` is a
/// library call without SSE4.1, and both give the same integer here.
#[inline]
fn snap(v: f64) -> i64 {
    const SHIFT: f64 = (1u64 << 40) as f64; // screen coordinates are far smaller
    (v * SUBPIXEL as f64 + (SHIFT + 0.5)) as i64 - (1i64 << 40)
}

/// Sets up the fan triangles of a clipped polygon, appending to `out`.
pub fn setup_polygon<const N: usize>(
    polygon: &[ClipVertex<N>],
    viewport: Viewport,
    cull_front: bool,
    cull_back: bool,
    primitive: u32,
    out: &mut Vec<SetupTriangle<N>>,
) {
    let n = polygon.len();
    if !(3..=MAX_CLIPPED_VERTICES).contains(&n) {
        return;
    }
    let mut screen = [(0i64, 0i64); MAX_CLIPPED_VERTICES];
    let mut exact = [(0f64, 0f64); MAX_CLIPPED_VERTICES];
    let mut inv_w = [0f64; MAX_CLIPPED_VERTICES];
    if !project(polygon, viewport, &mut screen, &mut exact, &mut inv_w) {
        return;
    }
    for k in 1..n - 1 {
        let idx = [0, k, k + 1];
        setup_triangle(
            polygon, &idx, &screen, &exact, &inv_w, viewport, cull_front, cull_back, primitive, out,
        );
    }
}

#[allow(clippy::too_many_arguments)]
fn setup_triangle<const N: usize>(
    verts: &[ClipVertex<N>],
    idx: &[usize; 3],
    screen: &[(i64, i64)],
    exact: &[(f64, f64)],
    inv_w: &[f64],
    viewport: Viewport,
    cull_front: bool,
    cull_back: bool,
    primitive: u32,
    out: &mut Vec<SetupTriangle<N>>,
) -> Option<()> {
    let p = idx.map(|i| screen[i]);
    let area2 = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
    if area2 == 0 {
        return None;
    }
    // y points down on screen, so a counter-clockwise world triangle has
    // negative area here.
    let front_facing = area2 < 0;
    if (front_facing && cull_front) || (!front_facing && cull_back) {
        return None;
    }
    let ordered = if area2 > 0 {
        *idx
    } else {
        [idx[0], idx[2], idx[1]]
    };
    let q = ordered.map(|i| screen[i]);
    let edges = [
        EdgeFunction::new(q[0], q[1]),
        EdgeFunction::new(q[1], q[2]),
        EdgeFunction::new(q[2], q[0]),
    ];

    // Bounding box of covered pixel centres: pixel i is sampled at
    // i * 256 + 128.
    let min_x = q.iter().map(|v| v.0).min()?;
    let max_x = q.iter().map(|v| v.0).max()?;
    let min_y = q.iter().map(|v| v.1).min()?;
    let max_y = q.iter().map(|v| v.1).max()?;
    let first = |m: i64| (m - HALF_PIXEL + SUBPIXEL - 1).div_euclid(SUBPIXEL);
    let last = |m: i64| (m - HALF_PIXEL).div_euclid(SUBPIXEL);
    let x0 = first(min_x).max(0);
    let y0 = first(min_y).max(0);
    let x1 = last(max_x).min(viewport.width as i64 - 1);
    let y1 = last(max_y).min(viewport.height as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return None;
    }

    // Interpolation planes from a canonical first vertex (the smallest
    // snapped position): the plane solve is then bit-identical whatever the
    // winding or starting vertex, so a shadow-volume cap gets exactly the
    // depth of the scene triangle it copies.
    let first_k = (0..3).min_by_key(|&k| (screen[idx[k]], k)).unwrap_or(0);
    let canon = [idx[first_k], idx[(first_k + 1) % 3], idx[(first_k + 2) % 3]];
    // Planes use the unsnapped positions: snapping moves a vertex by up to
    // 1/512 pixel, which near the horizon is a visible error in 1/w.
    let pts = canon.map(|i| exact[i]);
    let plane = |value: &dyn Fn(usize) -> f64| {
        Plane::through([0, 1, 2].map(|k| (pts[k].0, pts[k].1, value(canon[k]))))
    };
    let depth = plane(&|i| verts[i].position.z as f64 * inv_w[i]);
    // 1/w is only needed to divide varyings: skip its solve without them.
    let inv_w_plane = if N > 0 {
        plane(&|i| inv_w[i])
    } else {
        Plane::default()
    };
    let varyings = std::array::from_fn(|a| plane(&|i| verts[i].varyings[a] as f64 * inv_w[i]));
    // Pushed in place: a returned 170-byte struct would be copied twice.
    out.push(SetupTriangle {
        edges,
        bbox: [x0 as i32, y0 as i32, x1 as i32, y1 as i32],
        depth,
        inv_w: inv_w_plane,
        varyings,
        front_facing,
        primitive,
        small: max_x - min_x < 8 * SUBPIXEL && max_y - min_y < 8 * SUBPIXEL,
        block_i32: edges.iter().all(|e| e.a.abs() + e.b.abs() < 1 << 19),
        quad: NO_QUAD,
    });
    Some(())
}

/// Sets up the triangles `(v0, v1, v2)` and `(v0, v2, v3)` (primitives
/// `primitives`), exactly as two calls of [`setup_polygon`] would, and
/// merges them into one quad ([`QuadExtra`], appended to `quads`) when
/// both survive, face the same way, form a strictly convex quadrilateral
/// with at most two left and two right edges, and are not both small.
#[allow(clippy::too_many_arguments)]
pub fn setup_quad<const N: usize>(
    v: &[ClipVertex<N>; 4],
    viewport: Viewport,
    cull_front: bool,
    cull_back: bool,
    primitives: [u32; 2],
    out: &mut Vec<SetupTriangle<N>>,
    quads: &mut Vec<QuadExtra>,
) {
    let mut screen = [(0i64, 0i64); 4];
    let mut exact = [(0f64, 0f64); 4];
    let mut inv_w = [0f64; 4];
    if !project(v, viewport, &mut screen, &mut exact, &mut inv_w) {
        return;
    }
    let base = out.len();
    for (idx, prim) in [[0, 1, 2], [0, 2, 3]].iter().zip(primitives) {
        setup_triangle(
            v, idx, &screen, &exact, &inv_w, viewport, cull_front, cull_back, prim, out,
        );
    }
    if out.len() != base + 2 {
        return;
    }
    let (t1, t2) = (out[base], out[base + 1]);
    let orient = |a: usize, b: usize, c: usize| {
        let (p, q, r) = (screen[a], screen[b], screen[c]);
        ((q.0 - p.0) * (r.1 - p.1) - (r.0 - p.0) * (q.1 - p.1)).signum()
    };
    let turn = orient(0, 1, 2);
    let convex = [orient(0, 2, 3), orient(1, 2, 3), orient(3, 0, 1)]
        .iter()
        .all(|&o| o == turn);
    if !convex || t1.front_facing != t2.front_facing || (t1.small && t2.small) {
        return;
    }
    // Outer edges in positive order (see setup_triangle's ordering): the
    // first triangle's two, the second's two; the first's third edge is
    // the diagonal.
    let (outer, diagonal) = if turn > 0 {
        (
            [t1.edges[0], t1.edges[1], t2.edges[1], t2.edges[2]],
            t1.edges[2],
        )
    } else {
        (
            [t1.edges[1], t1.edges[2], t2.edges[0], t2.edges[1]],
            t1.edges[0],
        )
    };
    let left = outer.iter().filter(|e| e.a > 0).count();
    let right = outer.iter().filter(|e| e.a < 0).count();
    if left > 2 || right > 2 {
        return;
    }
    out.truncate(base);
    out.push(SetupTriangle {
        edges: [outer[0], outer[1], outer[2]],
        bbox: [
            t1.bbox[0].min(t2.bbox[0]),
            t1.bbox[1].min(t2.bbox[1]),
            t1.bbox[2].max(t2.bbox[2]),
            t1.bbox[3].max(t2.bbox[3]),
        ],
        small: false,
        block_i32: false,
        quad: quads.len() as u32,
        ..t1
    });
    quads.push(QuadExtra {
        edge: outer[3],
        diagonal,
        depth2: t2.depth,
    });
}

/// Projects and snaps `polygon`'s vertices; `false` for a degenerate one.
fn project<const N: usize>(
    polygon: &[ClipVertex<N>],
    viewport: Viewport,
    screen: &mut [(i64, i64)],
    exact: &mut [(f64, f64)],
    inv_w: &mut [f64],
) -> bool {
    let (w, h) = (viewport.width as f64, viewport.height as f64);
    for (k, v) in polygon.iter().enumerate() {
        let p = v.position;
        if !(p.w > 0.0) {
            return false; // degenerate (only a zero vector can get here)
        }
        let iw = 1.0 / p.w as f64;
        let sx = (p.x as f64 * iw * 0.5 + 0.5) * w;
        let sy = (0.5 - p.y as f64 * iw * 0.5) * h;
        screen[k] = (snap(sx), snap(sy));
        exact[k] = (sx, sy);
        inv_w[k] = iw;
    }
    true
}
