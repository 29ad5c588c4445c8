//! One receiver's whole bundle of shadow segments culled at once.
//!
//! Every shadow segment of a receiver starts at its origin `o` and ends
//! in the light, so all of them lie in one convex region: for any light
//! the bounding box of the segments `o + t · d` as traced, and for a rect
//! light the pyramid with apex `o` over the light's parallelogram (four
//! side planes through `o` and a cap in the light's plane). Besides, a
//! triangle behind the origin along every ray's dominant axis cannot be
//! hit (`SegmentHull::behind`, exact). [`Bvh::hull_leaves`] walks the tree
//! once per receiver with that region and collects the leaves that may
//! hold a triangle some segment could hit; [`Bvh::occluded_hull`] then
//! tests the rays only against those leaves when there are few, none at
//! all for a lit receiver (no ray is traced), and takes the rays' own
//! walks otherwise.
//!
//! **Same answer as [`Bvh::occluded`], bit for bit.** A ray's own walk
//! reports a hit from leaf `(node, slot)` iff the ray passes that leaf's
//! box (then it passes every box above it: see
//! `Bvh::packet_occluded`'s note) and the watertight test hits one of its
//! triangles. [`Bvh::occluded_hull`] runs exactly that per lane
//! (`Bvh::leaf_hits`) on every collected leaf. A leaf is left out only if
//! each of its triangles lies outside one bounding plane (or box face) of
//! the region by more than `HULL_MARGIN × R`, `R` the triangle's
//! L1 distance from `o`. The watertight test's verdict is exact for the
//! triangle as it sees it: the vertices minus the origin and sheared, in
//! f32, each step rounded relative to its result (`≤ 4 ε |v − o|` per
//! coordinate), and the ray's direction rounded (`ε |v − o|` at the
//! vertex's distance); the plane values here are f32 dot products of the
//! same differences (`≤ 4 ε R`); the box is that of the traced directions
//! themselves; the pyramid's planes are widened by `4 × 10⁻⁷ |x|` because
//! the sample points are within `2⁻²⁴ |x|` of the exact parallelogram
//! (their f64 position rounded once) and the directions within `2⁻²⁴
//! |x − o|` of `x − o`; the planes' f32 normals tilt by `≤ ε`. The sum is below `16 ε R ≈
//! 2 × 10⁻⁶ R`; the margin is five times that. So a triangle left out is
//! one no ray of the bundle can hit, and the rays' answers are those of
//! their own walks. `tests/it/reference.rs` holds the two paths against each
//! other over every receiver of the shipped scenes.

use super::packet::Packet;
use super::{Bvh, Node, Rel};
use crate::simd::f32x4;
use crate::simd::level::{level, Level};
use glam::{DVec3, Vec3};

/// The (dominant axis, sign) pairs `Ray::new` may pick for directions in
/// the box `[lo, hi]`, as bits `2 k + s` (`s` = 1: negative): one pair
/// when the box is strictly on one side of 0 along `k` and strictly
/// larger there in magnitude than along the others (`Ray::new`'s ties go
/// to the lower axis, so strictness makes the pick certain), else all six
/// (which only makes `SegmentHull::behind` stricter).
#[inline]
fn dominant_axes(lo: Vec3, hi: Vec3) -> u32 {
    let (lo, hi) = (lo.to_array(), hi.to_array());
    let reach = |j: usize| lo[j].abs().max(hi[j].abs());
    for k in 0..3 {
        let others = (0..3).filter(|&j| j != k).map(reach).fold(0.0f32, f32::max);
        if lo[k] > others {
            return 1 << (2 * k);
        }
        if -hi[k] > others {
            return 1 << (2 * k + 1);
        }
    }
    0b11_1111
}

/// A box or triangle is culled only when it is outside a bounding plane
/// by more than `HULL_MARGIN × R` (`R`: its L1 distance from the apex),
/// five times the rounding bound of the module docs.
const HULL_MARGIN: f32 = 1e-5;

/// The receiver's tangent plane culls a triangle only when each corner
/// `v` lies behind it by more than `TANGENT_MARGIN × |n|₁ × |v − o|∞`
/// (`n` the plane's normal as stored, `o` the apex). A tighter margin
/// than the other planes', because no rounding of the plane enters it:
/// the watertight test's verdict is the exact one for corners moved by at
/// most `5 ε |v − o|∞` per coordinate (`v − o` rounded, the shear's
/// product, difference and constant; module docs), which moves `n · v`
/// by at most `5 ε |n|₁ |v − o|∞`, and the f32 plane value here errs by
/// at most `4 ε |n|₁ |v − o|∞`: `TANGENT_MARGIN` is 1.9 times their sum
/// (`ε = 2⁻²⁴`). Every segment leaves `o` on the plane's front side
/// (`n · d > 0`, checked where the plane is added), so a triangle behind
/// it by that much is hit by none. This is what culls a ground the
/// receiver lies on where its rays are more horizontal than vertical
/// (`behind` needs the dominant axis to be the ground's normal): the
/// shadow-ray offset `ε_p ≥ 10⁻⁶ D` exceeds `10⁻⁶ |v − o|∞` for an
/// axis-aligned ground, where the general margin (`HULL_MARGIN × R`, `R`
/// up to the ground's size) kept it, and its rays were tested against it.
const TANGENT_MARGIN: f32 = 1e-6;

/// Most bounding planes: four sides and the cap (the receiver's tangent
/// plane is kept apart, with its own margin).
const MAX_PLANES: usize = 5;

/// The convex region holding every shadow segment of one receiver: the
/// box of the origin and the sample points, and for a rect light the
/// pyramid over the light from the origin. Coordinates are relative to the
/// origin.
#[derive(Debug, Clone)]
pub struct SegmentHull {
    origin: Vec3,
    /// The origin splatted per axis (`Ray::org`).
    org: [f32x4; 3],
    /// Box of the segments minus the origin, per axis.
    lo: [f32; 3],
    hi: [f32; 3],
    /// Bit `2 k + s`: some ray's dominant axis is `k` (`Ray::new`'s
    /// rule) with direction sign `s` (1: negative).
    axes: u32,
    /// Plane `j`: `normal · (p − o) ≤ offset` holds on every segment.
    normals: [Vec3; MAX_PLANES],
    offsets: [f32; MAX_PLANES],
    planes: usize,
    /// The receiver's tangent plane `n · (p − o) ≥ 0` (`n` as stored),
    /// culling with [`TANGENT_MARGIN`]: `TANGENT_MARGIN × |n|₁` here.
    tangent: Option<(Vec3, f32)>,
}

impl SegmentHull {
    /// The region of the segments `origin + t · dirs[i]`, `t ∈ (0, 1)`
    /// (the rays exactly as they are traced), bounded more tightly by the
    /// pyramid over `rect` when the samples lie in the parallelogram
    /// `center ± u ± v` (up to the rounding of their f32 positions), and
    /// by the receiver's tangent plane when `normal` (its geometric
    /// normal) is given and every direction faces it (see below).
    /// `None` when no direction is usable or the origin is not finite.
    ///
    /// The tangent plane: when every `d` has `n · d > 0`, the segments lie
    /// on the positive side of the plane through `o` with normal `n`, and
    /// the receiver's own surface, through `o − ε n`, on the other, so its
    /// triangles around the receiver (a facet of a convex object facing the
    /// light, and its neighbours curving away) are culled, with
    /// [`TANGENT_MARGIN`]. `n · d` is decided in f64 from the f32 values (the products
    /// are exact, the two sums round by at most 2⁻⁵² relative), against a
    /// threshold far above that rounding; the plane is `n` itself, as
    /// stored, so no tilt enters the margin argument. No plane when a
    /// direction fails, or `n` is zero or not finite.
    #[inline(always)]
    pub fn new(
        origin: Vec3,
        dirs: &[Vec3],
        rect: Option<(DVec3, DVec3, DVec3)>,
        normal: Option<Vec3>,
    ) -> Option<Self> {
        if !origin.is_finite() {
            return None;
        }
        // A NaN direction drops out of the min/max (it hits nothing); an
        // infinite one makes the box infinite, which culls nothing.
        // Compare-and-select (one `minss` / `maxss` each, which keep the
        // running bound when `d` is NaN) rather than `f32::min`'s NaN
        // handling: 2 % of the reference's instructions went here.
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let tangent = normal
            .filter(|n| n.is_finite() && *n != Vec3::ZERO && !dirs.is_empty())
            .map(|n| n.as_dvec3());
        let mut facing = tangent.is_some();
        for d in dirs {
            for axis in 0..3 {
                let c = d[axis];
                lo[axis] = if c < lo[axis] { c } else { lo[axis] };
                hi[axis] = if c > hi[axis] { c } else { hi[axis] };
            }
            if let (Some(n), true) = (tangent, facing) {
                let d = d.as_dvec3();
                facing = n.dot(d) > 1e-12 * n.abs().dot(d.abs());
            }
        }
        let mut hull =
            SegmentHull::of_directions(origin, Vec3::from_array(lo), Vec3::from_array(hi))?;
        if let Some((center, u, v)) = rect {
            hull.add_pyramid(origin.as_dvec3(), center, u, v);
        }
        if let (Some(n), true) = (tangent, facing) {
            // `n · (p − o) ≥ 0` on every segment.
            hull.push_tangent(n);
        }
        Some(hull)
    }

    /// The box of the segments from `origin` along directions in `[lo,
    /// hi]` (which decides the dominant axes), holding the origin, with
    /// no plane yet; `None` when the box is not finite.
    fn of_directions(origin: Vec3, lo: Vec3, hi: Vec3) -> Option<Self> {
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let axes = dominant_axes(lo, hi);
        let (lo, hi) = (lo.min(Vec3::ZERO), hi.max(Vec3::ZERO));
        Some(SegmentHull {
            origin,
            org: [
                f32x4::splat(origin.x),
                f32x4::splat(origin.y),
                f32x4::splat(origin.z),
            ],
            lo: lo.to_array(),
            hi: hi.to_array(),
            axes,
            normals: [Vec3::ZERO; MAX_PLANES],
            offsets: [0.0; MAX_PLANES],
            planes: 0,
            tangent: None,
        })
    }

    /// The region of every segment from `origin` to the rect light
    /// `center ± u ± v`, whatever its samples: the segments of
    /// [`SegmentHull::new`] for any sample set of that light lie in it, so
    /// a tree walk that finds no leaf in it proves every such segment
    /// clear before any sample is drawn. Its box is that of the origin
    /// and the corners, widened by `1e-6 (|c|∞ + |c − o|∞)` over the
    /// corners: a traced direction is `x − o` rounded to f32, with `x`
    /// the f32 rounding of a point of the parallelogram, so it lies
    /// within `2⁻²³ (|x|∞ + |x − o|∞)` per coordinate of the exact
    /// `p − o`, which the corners' box holds; the dominant axes come from
    /// the widened box of the directions, as in [`SegmentHull::new`]. The
    /// tangent plane is added only when every corner faces `normal` by
    /// more than `|n|₁` times that widening (then so does every traced
    /// direction, by [`SegmentHull::new`]'s rule). `None` when the origin
    /// or the light is not finite.
    pub fn over_light(
        origin: Vec3,
        (center, u, v): (DVec3, DVec3, DVec3),
        normal: Option<Vec3>,
    ) -> Option<Self> {
        let o = origin.as_dvec3();
        if !(o.is_finite() && center.is_finite() && u.is_finite() && v.is_finite()) {
            return None;
        }
        let corners = [
            center + u + v,
            center - u + v,
            center - u - v,
            center + u - v,
        ];
        let reach = corners
            .iter()
            .map(|c| c.abs().max_element() + (*c - o).abs().max_element())
            .fold(0.0, f64::max);
        let widen = 1e-6 * reach;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for c in corners {
            lo = lo.min(c - o);
            hi = hi.max(c - o);
        }
        let (lo, hi) = (lo - widen, hi + widen);
        // Rounded outwards to f32 by one more widening step (f32 keeps
        // 2⁻²⁴ relative, far below `widen`'s 1e-6 of the reach).
        let mut hull =
            SegmentHull::of_directions(origin, (lo - widen).as_vec3(), (hi + widen).as_vec3())?;
        hull.add_pyramid(o, center, u, v);
        if let Some(n) = normal.filter(|n| n.is_finite() && *n != Vec3::ZERO) {
            let n = n.as_dvec3();
            // Off by at most `|n|₁ · 2 widen` for a traced direction, and
            // `SegmentHull::new` asks `n · d > 1e-12 |n| · |d|` on top.
            let need = n.abs().element_sum() * 4.0 * widen;
            if corners.iter().all(|c| n.dot(*c - o) > need) {
                hull.push_tangent(n);
            }
        }
        Some(hull)
    }

    /// The pyramid over the parallelogram `c ± u ± v` from `o` (in f64):
    /// four side planes through `o` and two neighbouring corners, and the
    /// light's plane. None is added when `o` is (nearly) in the light's
    /// plane, where the pyramid degenerates; the box then bounds alone.
    fn add_pyramid(&mut self, o: DVec3, c: DVec3, u: DVec3, v: DVec3) {
        let corners = [c + u + v, c - u + v, c - u - v, c + u - v];
        let n = u.cross(v);
        let size = u.length() + v.length();
        if !(n.length() > 0.0) || !(size > 0.0) {
            return;
        }
        let n = n.normalize();
        let height = n.dot(o - c);
        if !(height.abs() > 1e-4 * size) {
            return;
        }
        // The samples' f32 positions are within 2⁻²⁴ |x| per coordinate of
        // the exact parallelogram: widen every plane by a few times that.
        let slack = 4e-7
            * corners
                .iter()
                .map(|p| p.abs().max_element())
                .fold(0.0, f64::max);
        for i in 0..4 {
            let a = corners[i] - o;
            let b = corners[(i + 1) % 4] - o;
            let mut side = a.cross(b);
            let len = side.length();
            if !(len > 0.0) {
                return;
            }
            side /= len;
            // Orient so the opposite corner is inside.
            if side.dot(corners[(i + 2) % 4] - o) > 0.0 {
                side = -side;
            }
            self.push_plane(side, slack);
        }
        // The cap: the side of the light's plane the origin is on.
        let cap = if height > 0.0 { -n } else { n };
        self.push_plane(cap, cap.dot(c - o) + slack);
    }

    /// The receiver's tangent plane with normal `n` through the apex,
    /// once every segment is known to leave the apex on its front side
    /// (`n · (p − o) ≥ 0` on every segment), tested with
    /// [`TANGENT_MARGIN`] alone: whatever the general margin would cull
    /// (`10⁻⁵` of the L1 reach), this one culls too (`10⁻⁶ |n|₁` of the
    /// largest coordinate, `|n|₁ ≤ √3`).
    fn push_tangent(&mut self, n: DVec3) {
        let n = n.as_vec3();
        self.tangent = Some((n, TANGENT_MARGIN * n.abs().element_sum()));
    }

    fn push_plane(&mut self, normal: DVec3, offset: f64) {
        if self.planes < MAX_PLANES {
            self.normals[self.planes] = normal.as_vec3();
            self.offsets[self.planes] = offset as f32;
            self.planes += 1;
        }
    }

    /// Bit mask of `node`'s children whose box may meet the region.
    #[inline(always)]
    fn hit_boxes(&self, node: &Node) -> u32 {
        let rel = Rel::new(node, &self.org);
        // A box behind every ray's origin along its dominant axis holds
        // only such vertices (`fl(v − o)` is monotone in `v`): `behind`.
        let mut axes = self.axes;
        let mut ahead = 0u32;
        while axes != 0 {
            let bit = axes.trailing_zeros() as usize;
            axes &= axes - 1;
            let (k, negative) = (bit / 2, bit % 2 == 1);
            ahead |= if negative {
                rel.lo[k].cmp_lt(f32x4::ZERO).move_mask()
            } else {
                rel.hi[k].cmp_gt(f32x4::ZERO).move_mask()
            };
        }
        // Each box's largest coordinate from the origin per axis: their
        // sum bounds its L1 distance (the planes' margin), their maximum
        // its farthest coordinate (the tangent plane's).
        let extent = [0, 1, 2].map(|axis| rel.lo[axis].abs().max(rel.hi[axis].abs()));
        let reach = extent[0] + extent[1] + extent[2];
        let margin = reach * f32x4::splat(HULL_MARGIN);
        let mut out = f32x4::ZERO.cmp_gt(f32x4::ZERO);
        for axis in 0..3 {
            out = out
                | rel.lo[axis].cmp_gt(f32x4::splat(self.hi[axis]) + margin)
                | rel.hi[axis].cmp_lt(f32x4::splat(self.lo[axis]) - margin);
        }
        if let Some((n, scale)) = self.tangent {
            // The box corner with the greatest `n · (p − o)` behind the
            // plane by the margin of its farthest coordinate: so is every
            // corner of every triangle inside.
            let pick = |axis: usize, k: f32| {
                let r = if k >= 0.0 { rel.hi[axis] } else { rel.lo[axis] };
                r * f32x4::splat(k)
            };
            let most = pick(0, n.x) + pick(1, n.y) + pick(2, n.z);
            let far = extent[0].max(extent[1]).max(extent[2]);
            out |= most.cmp_lt(far * f32x4::splat(-scale));
        }
        for j in 0..self.planes {
            let n = self.normals[j];
            // The box corner with the least `n · (p − o)`.
            let pick = |axis: usize, k: f32| {
                let r = if k >= 0.0 { rel.lo[axis] } else { rel.hi[axis] };
                r * f32x4::splat(k)
            };
            let least = pick(0, n.x) + pick(1, n.y) + pick(2, n.z);
            out |= least.cmp_gt(f32x4::splat(self.offsets[j]) + margin);
        }
        // Empty slots hold the point at +∞: never kept.
        let mut used = 0u32;
        for slot in 0..4 {
            if node.count[slot] > 0 || node.child[slot] != u32::MAX {
                used |= 1 << slot;
            }
        }
        !out.move_mask() & used & ahead
    }

    /// Whether every ray of the bundle sees the vertices whose `v − o`
    /// (as the watertight test computes it, in f32) lies in `[lo, hi]` at
    /// or behind its origin along its dominant axis. Then the test's depth
    /// `t_scaled` (a sum of products of the edge functions, all of the
    /// determinant's sign or 0, with those depths, all of the other sign
    /// or 0) cannot have the determinant's sign, so no ray hits: exact, no
    /// margin. This drops the receiver's own axis-aligned surface (a
    /// ground plane under a light above it).
    #[inline(always)]
    fn behind(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
        let mut axes = self.axes;
        while axes != 0 {
            let bit = axes.trailing_zeros() as usize;
            axes &= axes - 1;
            let (k, negative) = (bit / 2, bit % 2 == 1);
            let behind = if negative { lo[k] >= 0.0 } else { hi[k] <= 0.0 };
            if !behind {
                return false;
            }
        }
        true
    }

    /// Whether triangle `tri` may meet the region (see the module docs for
    /// the margin).
    #[inline(always)]
    fn may_touch(&self, tri: &[Vec3; 3]) -> bool {
        let r = tri.map(|p| p - self.origin);
        let reach = (r[0].abs().max(r[1].abs()).max(r[2].abs())).element_sum();
        let margin = reach * HULL_MARGIN;
        if !(margin.is_finite()) {
            return true;
        }
        let lo = r[0].min(r[1]).min(r[2]).to_array();
        let hi = r[0].max(r[1]).max(r[2]).to_array();
        if self.behind(lo, hi) {
            return false;
        }
        for axis in 0..3 {
            if lo[axis] > self.hi[axis] + margin || hi[axis] < self.lo[axis] - margin {
                return false;
            }
        }
        for j in 0..self.planes {
            let (n, d) = (self.normals[j], self.offsets[j] + margin);
            if r.iter().all(|v| n.dot(*v) > d) {
                return false;
            }
        }
        if let Some((n, scale)) = self.tangent {
            if r.iter().all(|v| n.dot(*v) < -scale * v.abs().max_element()) {
                return false;
            }
        }
        true
    }
}

impl Bvh {
    /// Collects into `leaves` (cleared first) the leaves `(node, slot)`
    /// holding a triangle that may meet `hull`, in depth-first order.
    /// Returns false (with `leaves` partly filled) as soon as more than
    /// `limit` are found.
    #[inline(always)]
    pub fn hull_leaves(
        &self,
        hull: &SegmentHull,
        leaves: &mut Vec<(u32, u32)>,
        limit: usize,
    ) -> bool {
        leaves.clear();
        if self.nodes.is_empty() {
            return true;
        }
        let mut full = false;
        self.walk(
            |node| hull.hit_boxes(node),
            |index, slot, range| {
                let Some(tris) = self.tris.leaf(range.start, range.len()) else {
                    return true;
                };
                if tris.iter().any(|t| hull.may_touch(&t)) {
                    if leaves.len() == limit {
                        full = true;
                        return false;
                    }
                    leaves.push((index, slot as u32));
                }
                true
            },
        );
        !full
    }

    /// [`Bvh::occluded_bundle`] for rays whose segments all lie in `hull`
    /// (built from the same origin and the samples the directions point
    /// at): the same answers, bit for bit (module docs), by testing only
    /// the leaves [`Bvh::hull_leaves`] keeps, or by the whole walk when
    /// more than `limit` are kept. `leaves` is scratch space. Returns
    /// false when the rays took the whole walk.
    #[allow(clippy::too_many_arguments)]
    pub fn occluded_hull(
        &self,
        hull: &SegmentHull,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut Vec<(u32, u32)>,
        limit: usize,
    ) -> bool {
        self.occluded_hull_at(level(), hull, dirs, t_max, out, leaves, limit)
    }

    /// [`Bvh::occluded_hull`] compiled for `level` (`simd::level`; the
    /// baseline copy where this CPU lacks it): the same answers at every
    /// level.
    #[allow(clippy::too_many_arguments)]
    pub fn occluded_hull_at(
        &self,
        level: Level,
        hull: &SegmentHull,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut Vec<(u32, u32)>,
        limit: usize,
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if level == Level::V3 && level.supported() {
            // SAFETY: the CPU has every feature the v3 copy enables
            // (`Level::supported`), its one requirement.
            return unsafe { self.occluded_hull_v3(hull, dirs, t_max, out, leaves, limit) };
        }
        let _ = level;
        self.occluded_hull_body(hull, dirs, t_max, out, leaves, limit)
    }

    /// [`Bvh::occluded_hull_body`] compiled for `Level::V3`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn occluded_hull_v3(
        &self,
        hull: &SegmentHull,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut Vec<(u32, u32)>,
        limit: usize,
    ) -> bool {
        self.occluded_hull_body(hull, dirs, t_max, out, leaves, limit)
    }

    /// The hull walk itself, inlined into each level's copy.
    #[inline(always)]
    fn occluded_hull_body(
        &self,
        hull: &SegmentHull,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut Vec<(u32, u32)>,
        limit: usize,
    ) -> bool {
        out.fill(false);
        if self.nodes.is_empty() || !(t_max > 0.0) {
            return true;
        }
        if !self.hull_leaves(hull, leaves, limit) {
            self.occluded_bundle_body(hull.origin, dirs, t_max, out);
            return false;
        }
        self.occluded_leaves_body(hull.origin, dirs, t_max, out, leaves);
        true
    }

    /// [`Bvh::occluded_hull`]'s answers when `leaves` already holds every
    /// leaf some segment from `origin` along `dirs` may hit (a
    /// [`Bvh::hull_leaves`] list of a region holding all of them, kept
    /// within its limit): the rays are tested against those leaves only,
    /// each lane passing the leaf's own box first, so every answer is the
    /// ray's own walk's. `out` is cleared first.
    pub fn occluded_leaves(
        &self,
        origin: Vec3,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut [(u32, u32)],
    ) {
        #[cfg(target_arch = "x86_64")]
        if level() == Level::V3 && Level::V3.supported() {
            // SAFETY: the CPU has every feature the v3 copy enables
            // (`Level::supported`), its one requirement.
            return unsafe { self.occluded_leaves_v3(origin, dirs, t_max, out, leaves) };
        }
        self.occluded_leaves_body(origin, dirs, t_max, out, leaves)
    }

    /// [`Bvh::occluded_leaves_body`] compiled for `Level::V3`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn occluded_leaves_v3(
        &self,
        origin: Vec3,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut [(u32, u32)],
    ) {
        self.occluded_leaves_body(origin, dirs, t_max, out, leaves)
    }

    /// The leaves' test itself, inlined into each level's copy.
    #[inline(always)]
    fn occluded_leaves_body(
        &self,
        origin: Vec3,
        dirs: &[Vec3],
        t_max: f32,
        out: &mut [bool],
        leaves: &mut [(u32, u32)],
    ) {
        out.fill(false);
        if self.nodes.is_empty() || !(t_max > 0.0) {
            return;
        }
        if leaves.is_empty() {
            return;
        }
        let mut packet = Packet::empty();
        for (chunk, res) in dirs
            .chunks(super::PACKET)
            .zip(out.chunks_mut(super::PACKET))
        {
            packet.load(origin, chunk, t_max);
            if packet.valid == 0 {
                continue;
            }
            let mut hit = 0u32;
            for i in 0..leaves.len() {
                let (index, slot) = leaves[i];
                let Some(node) = self.nodes.get(index as usize) else {
                    continue;
                };
                let found = self.leaf_hits(&packet, node, slot as usize, packet.valid & !hit);
                if found != 0 {
                    hit |= found;
                    // Try this leaf first next time: the order of the
                    // leaves changes no answer, only how soon lanes stop.
                    leaves.swap(0, i);
                    if hit == packet.valid {
                        break;
                    }
                }
            }
            for (lane, r) in res.iter_mut().enumerate() {
                *r = hit >> lane & 1 == 1;
            }
        }
    }
}
