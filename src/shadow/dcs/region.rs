//! Where an edge without a bounded wedge can matter: a convex outer bound
//! of its penumbra region, as half-spaces, for cheap per-tile and
//! per-receiver rejection.
//!
//! A receiver `p` sees the edge `E = [v0, v1]` over the light `L` only if
//! it lies on a ray from a light point `x` through a point `a` of the
//! edge, beyond it: `p = a + t (a − x)`, `t ≥ 0`. Writing `a` and `x` as
//! convex combinations of the edge's ends and of the light's bounding
//! corners `x_j`, `a − x = Σ α_i β_j (v_i − x_j)`, so every such `p` lies
//! in `R = conv{v0, v1} + cone{v_i − x_j}` — a convex polyhedron. Its
//! facets are planes spanned by two generators, or by the edge and one
//! generator; a candidate plane with normal `n` bounds `R` when
//! `n · d ≥ 0` for every generator `d`, at `h = min_i n · v_i`. The few
//! edges whose line pierces the light (no convex wedge exists) get these
//! planes instead of a wedge: a receiver or a box of receivers wholly
//! below one of them cannot be affected by the edge.

use crate::simd::f64x4;
use glam::DVec3;

/// [`RegionBound::admits`]'s kernel over `$lane` lanes (made by
/// `$splat(v)` and `$new(array)`), in names both the facade's `f64x4`
/// and `simd::avx::F64x4` have, so it compiles on each (see
/// `edge_lanes`).
macro_rules! admits_kernel {
    ($lane:ty, $splat:path, $new:path, $bound:ident, $block:ident) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, BitAnd, BitOr, Mul, Sub};
        let mut keep = $block.valid;
        for g in 0..4 {
            if (keep >> (4 * g)) & 0xF == 0 {
                continue;
            }
            let (x, y, z): ($lane, $lane, $lane) =
                ($new($block.x[g]), $new($block.y[g]), $new($block.z[g]));
            // `DVec3::dot`'s order: `(n_x x + n_y y) + n_z z`.
            let dot = |n: DVec3| {
                $splat(n.x)
                    .mul(x)
                    .add($splat(n.y).mul(y))
                    .add($splat(n.z).mul(z))
            };
            let mut out = 0;
            if let Some((faces, slack)) = $bound.dihedral() {
                let d0 = dot(faces[0].0).sub($splat(faces[0].1));
                let d1 = dot(faces[1].0).sub($splat(faces[1].1));
                let (up, down) = ($splat(slack), $splat(-slack));
                let front = d0.cmp_gt(up).bitand(d1.cmp_gt(up));
                let behind = d0.cmp_lt(down).bitand(d1.cmp_lt(down));
                out = front.bitor(behind).move_mask();
            }
            for (n, h) in $bound.planes() {
                if out == 0xF {
                    break;
                }
                out |= dot(n).cmp_lt($splat(h)).move_mask();
            }
            keep &= !((out as u16) << (4 * g));
        }
        keep
    }};
}

/// [`RegionBound::keep_lanes`]' loop over `$lane` lanes: each item whose
/// region ([`excludes_box_kernel!`]) does not exclude one of the boxes,
/// into `$out`. (A separate loop for one box was measured: 0.9 % more
/// instructions in the counter pass, so there is none.)
macro_rules! keep_kernel {
    ($lane:ty, $splat:path, $new:path, $items:ident, $region_of:ident, $boxes:ident, $out:ident) => {{
        let boxes = $boxes.as_slice();
        for item in $items {
            if let Some(region) = $region_of(item) {
                if boxes
                    .iter()
                    .any(|&(lo, hi)| !excludes_box_kernel!($lane, $splat, $new, region, lo, hi))
                {
                    $out.push(item);
                }
            }
        }
    }};
}

/// How much smaller two boxes must be than one (the sum of their
/// diagonals against its diagonal) for [`ReceiverBoxes::of`] to keep two.
const SPLIT_GAIN: f64 = 0.75;

/// A block's receivers as one box, or two where they fall apart into two
/// clusters: a sphere's silhouette against the ground far behind it gives
/// one box spanning the empty depth between them, which meets the regions
/// of every edge on the way. Two boxes reject an edge only if both do, so
/// they let through every edge whose region holds a receiver, as one box
/// does (at 512² on 81 spheres of 1.0M triangles, the 14 % of 4² blocks
/// with such a box took 89 % of the per-receiver region tests).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverBoxes {
    boxes: [(DVec3, DVec3); 2],
    len: usize,
}

impl ReceiverBoxes {
    /// The boxes of `points` (`None` without points): the bounding box,
    /// split at the middle of its longest side into the boxes of the
    /// points on either side when their diagonals sum to less than
    /// [`SPLIT_GAIN`] times its own.
    pub fn of(points: impl Iterator<Item = DVec3> + Clone) -> Option<ReceiverBoxes> {
        let grow = |b: Option<(DVec3, DVec3)>, p: DVec3| {
            Some(match b {
                None => (p, p),
                Some((lo, hi)) => (p.min(lo), p.max(hi)),
            })
        };
        let whole = points.clone().fold(None, grow)?;
        let one = ReceiverBoxes {
            boxes: [whole; 2],
            len: 1,
        };
        let (lo, hi) = whole;
        let e = hi - lo;
        let axis = if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        };
        let mid = 0.5 * (lo[axis] + hi[axis]);
        let (mut below, mut above) = (None, None);
        for p in points {
            if p[axis] < mid {
                below = grow(below, p);
            } else {
                above = grow(above, p);
            }
        }
        let diagonal = |(lo, hi): (DVec3, DVec3)| (hi - lo).length();
        match (below, above) {
            (Some(a), Some(b)) if diagonal(a) + diagonal(b) < SPLIT_GAIN * diagonal(whole) => {
                Some(ReceiverBoxes {
                    boxes: [a, b],
                    len: 2,
                })
            }
            _ => Some(one),
        }
    }

    /// One box.
    pub fn single(lo: DVec3, hi: DVec3) -> ReceiverBoxes {
        ReceiverBoxes {
            boxes: [(lo, hi); 2],
            len: 1,
        }
    }

    /// The boxes, one or two.
    pub fn as_slice(&self) -> &[(DVec3, DVec3)] {
        &self.boxes[..self.len]
    }
}

/// Half-spaces `n · y ≥ h` (unit `n`) whose intersection holds an edge's
/// penumbra region.
#[derive(Debug, Clone, Default)]
pub struct RegionBound {
    /// The planes four to a group, structure-of-arrays ([`Planes4`]):
    /// the only copy (one region per candidate edge, a million of them at
    /// 4M triangles), read plane by plane by [`RegionBound::planes`].
    quads: Vec<Planes4>,
    /// How many planes `quads` holds.
    count: usize,
    /// The edge's two face planes when it only matters where they
    /// disagree (see [`RegionBound::with_dihedral`]), and the slack, in
    /// SoA lanes ([`Dihedral4`]); [`RegionBound::dihedral`] reads them
    /// back.
    dihedral4: Option<Dihedral4>,
}

/// Four planes of [`RegionBound::planes`] in structure-of-arrays form:
/// lane `k` of `n[axis]` and `h` is plane `4 i + k` of the group `i`.
/// Unused lanes have `n = 0`, `h = −∞`: they exclude nothing (`0 · x`
/// sums to 0 or NaN, neither of which is below −∞). Plain arrays, so
/// that the facade's lanes and AVX registers load them alike.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
struct Planes4 {
    n: [[f64; 4]; 3],
    h: [f64; 4],
}

/// The dihedral test's two face planes in four lanes: face 0 at the box
/// corner least far along its normal, face 0 at the farthest, then face 1
/// the same.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
struct Dihedral4 {
    /// Lanes `[n0, n0, n1, n1]` per axis.
    n: [[f64; 4]; 3],
    /// `[h0, h0, h1, h1]`.
    h: [f64; 4],
    /// Per axis, the lanes that take the box's `hi` (a mask: all bits
    /// set, or none): the scalar twin's `(n ≥ 0) == far`, so the
    /// farthest lanes where `n ≥ 0` (−0 included) and the least far ones
    /// where not (NaN included).
    take_hi: [[f64; 4]; 3],
    slack: [f64; 4],
    neg_slack: [f64; 4],
}

/// Lanes of [`Dihedral4`] at the least far corners (both faces)…
const NEAR_LANES: u32 = 0b0101;
/// …and at the farthest.
const FAR_LANES: u32 = 0b1010;

impl Dihedral4 {
    fn new(faces: [(DVec3, f64); 2], slack: f64) -> Dihedral4 {
        let lanes = |f: &dyn Fn(usize) -> f64| [f(0), f(0), f(1), f(1)];
        let all = f64::from_bits(u64::MAX);
        let mask = |f: &dyn Fn(usize) -> bool| [0, 1, 2, 3].map(|l| if f(l) { all } else { 0.0 });
        let take_hi =
            |axis: usize| mask(&|lane: usize| (faces[lane / 2].0[axis] >= 0.0) == (lane % 2 == 1));
        Dihedral4 {
            n: [0, 1, 2].map(|axis| lanes(&|f| faces[f].0[axis])),
            h: lanes(&|f| faces[f].1),
            take_hi: [take_hi(0), take_hi(1), take_hi(2)],
            slack: [slack; 4],
            neg_slack: [-slack; 4],
        }
    }

    /// The scalar twin's verdict from the lanes' masks of signed
    /// distances above the slack (`front`) and below its negative
    /// (`behind`): in front of both faces at their least far corners, or
    /// behind both at their farthest.
    #[inline(always)]
    fn excludes(front: u32, behind: u32) -> bool {
        front & NEAR_LANES == NEAR_LANES || behind & FAR_LANES == FAR_LANES
    }
}

/// [`RegionBound::excludes_box`]'s kernel over `$lane` lanes (made by
/// `$splat(v)` and `$new(array)`), in names both the facade's `f64x4`
/// and `simd::avx::F64x4` have, as [`admits_kernel!`].
///
/// Per plane lane: `n_a f_a` with `f` the box corner furthest along `n`
/// (the scalar twin's `hi` where `n_a ≥ 0`, −0 included, `lo`
/// elsewhere), then `(n_x f_x + n_y f_y) + n_z f_z` in `DVec3::dot`'s
/// order. The product is taken as `max(n_a lo_a, n_a hi_a)` (`maxpd`'s
/// rule, the facade's `max`: `if a > b { a } else { b }`), which for
/// `lo_a ≤ hi_a`, neither NaN, is the twin's product bit for bit —
/// rounded products are monotone, so for `n_a ≥ 0` (or ±0, or an
/// infinite corner making `0 · ∞` NaN on either side) `n_a lo_a > n_a
/// hi_a` never holds and `n_a hi_a` is returned, and for `n_a < 0` it is
/// `n_a lo_a` unless the two are equal — the same value, apart from the
/// sign of a zero when `lo_a = −0`, `hi_a = +0`. A zero's sign changes a
/// rounded sum only when the sum is zero, and `−0 < h` is `+0 < h`: the
/// verdict per plane is the twin's. (Receivers' bounds are min / max of
/// positions, which skip NaN, so `lo ≤ hi` and neither is NaN.)
macro_rules! excludes_box_kernel {
    ($lane:ty, $splat:path, $new:path, $bound:ident, $lo:ident, $hi:ident) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul, Sub};
        let lo4: [$lane; 3] = [$splat($lo.x), $splat($lo.y), $splat($lo.z)];
        let hi4: [$lane; 3] = [$splat($hi.x), $splat($hi.y), $splat($hi.z)];
        let dihedral = $bound.dihedral4.as_ref().is_some_and(|f| {
            // Per lane its corner (the scalar twin's pick), then
            // `n · corner − h` in `DVec3::dot`'s order.
            let c = |axis: usize| $new(f.take_hi[axis]).blend(hi4[axis], lo4[axis]);
            let d = $new(f.n[0])
                .mul(c(0))
                .add($new(f.n[1]).mul(c(1)))
                .add($new(f.n[2]).mul(c(2)))
                .sub($new(f.h));
            Dihedral4::excludes(
                d.cmp_gt($new(f.slack)).move_mask(),
                d.cmp_lt($new(f.neg_slack)).move_mask(),
            )
        });
        dihedral
            || $bound.quads.iter().any(|q| {
                let term = |a: usize| {
                    let n = $new(q.n[a]);
                    n.mul(lo4[a]).max(n.mul(hi4[a]))
                };
                let d = term(0).add(term(1)).add(term(2));
                d.cmp_lt($new(q.h)).move_mask() != 0
            })
    }};
}

/// Sixteen receivers (a 4 × 4 block of pixels, row by row) in four lane
/// groups of four, structure-of-arrays, for testing one region against
/// all of them at once ([`RegionBound::admits`]).
#[derive(Debug, Clone, Copy)]
pub struct ReceiverBlock {
    x: [[f64; 4]; 4],
    y: [[f64; 4]; 4],
    z: [[f64; 4]; 4],
    /// Bit `k` set where receiver `k` exists (a surface pixel).
    valid: u16,
}

impl ReceiverBlock {
    /// The block of `points` (`None` where a pixel has no receiver).
    pub fn new(points: &[Option<DVec3>; 16]) -> ReceiverBlock {
        let lanes = |axis: usize| {
            std::array::from_fn(|g| {
                std::array::from_fn(|k| points[4 * g + k].map_or(0.0, |p| p[axis]))
            })
        };
        let valid = points
            .iter()
            .enumerate()
            .fold(0u16, |m, (k, p)| m | (u16::from(p.is_some()) << k));
        ReceiverBlock {
            x: lanes(0),
            y: lanes(1),
            z: lanes(2),
            valid,
        }
    }
}

/// A cone's unit generators four to a lane group, for the facet test of
/// a candidate normal: no generator may point below the plane (see
/// [`RegionBound::new`]). Unused lanes are zero vectors, whose dot is 0
/// and passes.
struct Generators4 {
    /// The first `len` groups hold the generators.
    groups: [[[f64; 4]; 3]; GENERATOR_GROUPS],
    len: usize,
    /// Test in AVX registers ([`Generators4::bound_avx`]); set only where
    /// the CPU has AVX, by the v3 copy of [`RegionBound::new`].
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    avx: bool,
}

/// [`Generators4::bound`]'s kernel over `$lane` lanes (made by
/// `$splat(v)` and `$new(array)`), in names both the facade's `f64x4`
/// and `simd::avx::F64x4` have: the same verdicts on each.
macro_rules! generators_bound_kernel {
    ($lane:ty, $splat:path, $new:path, $g:expr, $n:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul};
        let (g, n): (&Generators4, DVec3) = ($g, $n);
        let (x, y, z): ($lane, $lane, $lane) = ($splat(n.x), $splat(n.y), $splat(n.z));
        let (low, high): ($lane, $lane) = ($splat(-1e-9), $splat(1e-9));
        let (mut up, mut down) = (true, true);
        for lanes in &g.groups[..g.len] {
            let dot = x
                .mul($new(lanes[0]))
                .add(y.mul($new(lanes[1])))
                .add(z.mul($new(lanes[2])));
            up &= dot.cmp_ge(low).move_mask() == 0b1111;
            down &= dot.cmp_le(high).move_mask() == 0b1111;
            if !(up || down) {
                break;
            }
        }
        (up, down)
    }};
}

/// Most lane groups of [`Generators4`]: 32 generators, an edge's two
/// ends or a box's eight corners against at most four light corners
/// (a sphere light's eight bounding corners meet only edges).
const GENERATOR_GROUPS: usize = 8;

impl Generators4 {
    /// The generators four to a group, in a fixed array (no allocation
    /// per region: the allocator was a sixth of the regions' build);
    /// `None` past [`GENERATOR_GROUPS`] groups.
    fn new(generators: &[DVec3]) -> Option<Generators4> {
        let mut groups = [[[0.0; 4]; 3]; GENERATOR_GROUPS];
        let len = generators.len().div_ceil(4);
        if len > GENERATOR_GROUPS {
            return None;
        }
        for (lanes, g) in groups.iter_mut().zip(generators.chunks(4)) {
            for (k, d) in g.iter().enumerate() {
                for (axis, lane) in lanes.iter_mut().enumerate() {
                    lane[k] = d[axis];
                }
            }
        }
        Some(Generators4 {
            groups,
            len,
            avx: false,
        })
    }

    /// Whether `n` and whether `−n` bound the cone: every generator `d`
    /// has `n · d ≥ −1e-9`, respectively `(−n) · d ≥ −1e-9`. The dots are
    /// `DVec3::dot`'s operations in its order (products commute
    /// exactly), and `(−n) · d` is `−(n · d)` up to the sign of a zero,
    /// so the second test is `n · d ≤ 1e-9`: the scalar twin's verdicts.
    #[inline(always)]
    fn bound(&self, n: DVec3) -> (bool, bool) {
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only by the v3 copy of
            // `RegionBound::new`, which runs only where the CPU has
            // x86-64-v3's features, AVX among them.
            return unsafe { self.bound_avx(n) };
        }
        generators_bound_kernel!(f64x4, f64x4::splat, f64x4::new, self, n)
    }

    /// [`Generators4::bound`] in AVX registers.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    fn bound_avx(&self, n: DVec3) -> (bool, bool) {
        use crate::simd::avx::F64x4;
        generators_bound_kernel!(F64x4, F64x4::splat, F64x4::new, self, n)
    }
}

/// Generators and their tags `(point, corner)` ([`cone_generators`]).
type Tagged = (Vec<DVec3>, Vec<(u8, u8)>);

/// The unit directions `v − x` from each light corner `x` to each of
/// `points` (zero and non-finite ones left out): the generators of the
/// cone whose facets bound a region, each with its tag `(point, corner)`.
fn cone_generators(points: &[DVec3], corners: &[DVec3]) -> Tagged {
    let mut generators = Vec::with_capacity(points.len() * corners.len());
    let mut tags = Vec::with_capacity(points.len() * corners.len());
    cone_generators_into(points, corners, &mut generators, &mut tags);
    (generators, tags)
}

/// [`cone_generators`] into `generators` and `tags` (cleared first).
fn cone_generators_into(
    points: &[DVec3],
    corners: &[DVec3],
    generators: &mut Vec<DVec3>,
    tags: &mut Vec<(u8, u8)>,
) {
    generators.clear();
    tags.clear();
    for (i, &v) in points.iter().enumerate() {
        for (j, &x) in corners.iter().enumerate() {
            let d = v - x;
            if d.length_squared() > 0.0 && d.is_finite() {
                generators.push(d.normalize());
                tags.push((i as u8, j as u8));
            }
        }
    }
}

/// Whether two generators (by their tags) can span a facet of the cone
/// `cone(A − B)` over a convex set of points `A` and a light's corners
/// `B`: a facet touches the set `A − B` along an edge, and the edges of
/// that Minkowski difference are translates of edges of `A` (two points,
/// one light corner) or of `B` (one point, two light corners). Pairs
/// from two points and two corners only repeat such planes (or miss the
/// facet test), so they are not made: 28 → 16 pairs for an edge, 496 →
/// 160 for a cluster's box.
#[inline(always)]
fn may_span_facet(a: (u8, u8), b: (u8, u8)) -> bool {
    a.0 == b.0 || a.1 == b.1
}

/// Whether the directions `generators` and `along` all lie in one plane
/// through the origin (within 1e-7 of it, as the facet filter below
/// judges a direction to lie on a plane), or there are too few to tell.
fn coplanar(generators: &[DVec3], along: DVec3) -> bool {
    let along = along.normalize_or_zero();
    let dirs = || {
        generators
            .iter()
            .chain(std::iter::once(&along))
            .filter(|d| **d != DVec3::ZERO)
    };
    // A quick no first (nearly every region): were all the unit
    // directions within 1e-7 of one plane through the origin, any three
    // would have a determinant of at most 3e-7 (each is a part in the
    // plane, of length ≤ 1, plus at most 1e-7 along its normal; the
    // parts in the plane have determinant 0, and each term with one
    // normal part is at most 1e-7). So three with more than 1e-6 are
    // not coplanar, as the full test below would find.
    let mut it = dirs();
    if let (Some(a), Some(b)) = (it.next(), it.next()) {
        let ab = a.cross(*b);
        if it.any(|c| ab.dot(*c).abs() > 1e-6) {
            return false;
        }
    }
    // The normal of the best-spread pair.
    let mut best = DVec3::ZERO;
    for (k, a) in dirs().enumerate() {
        for b in dirs().skip(k + 1) {
            let n = a.cross(*b);
            if n.length_squared() > best.length_squared() {
                best = n;
            }
        }
    }
    if best.length_squared() < 1e-14 {
        return true;
    }
    let n = best.normalize();
    dirs().all(|d| n.dot(*d).abs() <= 1e-7)
}

/// Whether `n` and whether `−n` bound the cone (no generator points more
/// than 1e-9 below the plane: the two that span it give ±rounding, and a
/// unit generator 1e-9 below tilts out of the half-space by 1e-9 per unit
/// of length, far inside `slack` over any scene-sized distance): four
/// generators at a time, or one at a time (the scalar twin).
// One lives on the stack per region build; boxing the large variant would
// bring back the allocation `Generators4`'s fixed array removed.
#[allow(clippy::large_enum_variant)]
enum FacetTest<'a> {
    Simd(Generators4),
    Scalar(&'a [DVec3]),
}

impl<'a> FacetTest<'a> {
    fn new(generators: &'a [DVec3], simd: bool) -> FacetTest<'a> {
        match simd.then(|| Generators4::new(generators)).flatten() {
            Some(g) => FacetTest::Simd(g),
            None => FacetTest::Scalar(generators),
        }
    }

    /// Of the unit normal along candidate `n` (none when `n` is nearly 0
    /// or not finite) and its opposite, those that bound the cone, `n`
    /// first.
    #[inline(always)]
    fn facets(&self, n: DVec3) -> impl Iterator<Item = DVec3> {
        let len = n.length();
        let usable = len > 1e-12 && len.is_finite();
        let n = n / len;
        let (up, down) = if usable {
            self.bound(n)
        } else {
            (false, false)
        };
        [(n, up), (-n, down)]
            .into_iter()
            .filter_map(|(n, keep)| keep.then_some(n))
    }

    #[inline(always)]
    fn bound(&self, n: DVec3) -> (bool, bool) {
        match self {
            FacetTest::Simd(g) => g.bound(n),
            FacetTest::Scalar(g) => (
                g.iter().all(|d| n.dot(*d) >= -1e-9),
                g.iter().all(|d| (-n).dot(*d) >= -1e-9),
            ),
        }
    }
}

thread_local! {
    /// [`RegionBound::new`]'s plane buffer, kept between calls.
    static PLANES: std::cell::Cell<Vec<(DVec3, f64)>> = const { std::cell::Cell::new(Vec::new()) };
    /// [`RegionBound::new`]'s generator and tag buffers, kept between
    /// calls.
    static GENERATORS: std::cell::Cell<Tagged> =
        const { std::cell::Cell::new((Vec::new(), Vec::new())) };
}

impl RegionBound {
    /// The bound of `planes`, with their SoA groups.
    fn from_planes(planes: &[(DVec3, f64)]) -> RegionBound {
        let quads = planes
            .chunks(4)
            .map(|group| {
                let mut n = [[0.0; 4]; 3];
                let mut h = [f64::NEG_INFINITY; 4];
                for (k, &(normal, offset)) in group.iter().enumerate() {
                    for (axis, lanes) in n.iter_mut().enumerate() {
                        lanes[k] = normal[axis];
                    }
                    h[k] = offset;
                }
                Planes4 { n, h }
            })
            .collect();
        RegionBound {
            quads,
            count: planes.len(),
            dihedral4: None,
        }
    }

    /// The planes `(n, h)`, in their order: lane `k` of group `i` is plane
    /// `4 i + k` (the same values as built).
    #[inline(always)]
    pub fn planes(&self) -> impl Iterator<Item = (DVec3, f64)> + '_ {
        (0..self.count).map(|i| {
            let (q, k) = (&self.quads[i / 4], i % 4);
            (DVec3::new(q.n[0][k], q.n[1][k], q.n[2][k]), q.h[k])
        })
    }

    /// The two face planes and the slack of
    /// [`RegionBound::with_dihedral`], read back from their lanes (face
    /// `f` is lane `2 f`).
    #[inline(always)]
    fn dihedral(&self) -> Option<([(DVec3, f64); 2], f64)> {
        self.dihedral4.as_ref().map(|d| {
            let face = |l: usize| (DVec3::new(d.n[0][l], d.n[1][l], d.n[2][l]), d.h[l]);
            ([face(0), face(2)], d.slack[0])
        })
    }

    /// The bound of edge `v0 v1` against a light inside the convex hull of
    /// `corners`. `slack` (a distance) moves every plane outward, to cover
    /// rounding of the receivers' positions. The facet test runs four
    /// generators at a time (`Generators4`), once for both `n` and `−n`;
    /// `new_scalar` is the same constructor with the scalar facet test.
    pub fn new(v0: DVec3, v1: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        Self::edge_bound(v0, v1, corners, slack, true)
    }

    /// [`RegionBound::new`] with the scalar facet test (its twin).
    #[cfg(test)]
    fn new_scalar(v0: DVec3, v1: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        Self::edge_bound(v0, v1, corners, slack, false)
    }

    fn edge_bound(v0: DVec3, v1: DVec3, corners: &[DVec3], slack: f64, simd: bool) -> RegionBound {
        #[cfg(target_arch = "x86_64")]
        if simd && crate::simd::level::runs_v3() {
            // SAFETY: `runs_v3` checked that the CPU has every feature the
            // v3 copy enables, its one requirement.
            return unsafe { Self::edge_bound_v3(v0, v1, corners, slack) };
        }
        Self::edge_bound_body(v0, v1, corners, slack, simd, false)
    }

    /// [`RegionBound::edge_bound`] compiled for `Level::V3`
    /// (`simd::level`), with the facet test in AVX registers: the same
    /// code and verdicts (no FMA).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]
    fn edge_bound_v3(v0: DVec3, v1: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        Self::edge_bound_body(v0, v1, corners, slack, true, true)
    }

    /// [`RegionBound::edge_bound`] itself, inlined into each copy.
    #[inline(always)]
    fn edge_bound_body(
        v0: DVec3,
        v1: DVec3,
        corners: &[DVec3],
        slack: f64,
        simd: bool,
        avx: bool,
    ) -> RegionBound {
        let (mut buffer, mut tags) = GENERATORS.take();
        cone_generators_into(&[v0, v1], corners, &mut buffer, &mut tags);
        let generators = &buffer[..];
        let along = v1 - v0;
        let mut facets = FacetTest::new(generators, simd);
        if let FacetTest::Simd(g) = &mut facets {
            g.avx = avx;
        }
        let facets = facets;
        // Dozens of planes per edge, for tens of thousands of edges: grown
        // in a per-thread buffer and copied once, not reallocated as they
        // come (the allocator was a fifth of the wedge build).
        let mut planes = PLANES.take();
        planes.clear();
        let mut consider = |n: DVec3| {
            for n in facets.facets(n) {
                // The same plane comes from several pairs (the edge and
                // its two generators towards one light corner span one
                // plane): keep it once.
                if planes
                    .iter()
                    .any(|&(m, _): &(DVec3, f64)| m.dot(n) > 1.0 - 1e-12)
                {
                    continue;
                }
                planes.push((n, n.dot(v0).min(n.dot(v1)) - slack));
            }
        };
        // Facet normals: across two spanning directions, and (only for
        // flat cones, where the region lies in a plane) within their
        // plane, perpendicular to either. Elsewhere those in-plane
        // candidates touch the region along one line at most and would
        // be dropped below: not making them saves two thirds of the
        // facet tests.
        let flat_cone = coplanar(generators, along);
        let mut span = |a: DVec3, b: DVec3| {
            let n = a.cross(b);
            consider(n);
            if flat_cone {
                consider(n.cross(a));
                consider(n.cross(b));
            }
        };
        for (k, (&a, &ta)) in generators.iter().zip(&tags).enumerate() {
            for (&b, &tb) in generators[k + 1..].iter().zip(&tags[k + 1..]) {
                if may_span_facet(ta, tb) {
                    span(a, b);
                }
            }
            span(along, a);
        }
        // A supporting plane that touches the region along one line only
        // (a cone's edge) adds nothing to its facets but a test: keep the
        // planes holding two independent directions of the region (its
        // generators, the edge). Dropping a plane only loosens the bound,
        // so this is safe whatever the tolerance; a flat region (both
        // sides of one plane bound it) keeps all, its sides being such
        // planes. (36 planes per edge on average on `spheres.toml` before,
        // 26 without duplicates, 6 after.)
        let flat = planes
            .iter()
            .any(|&(n, _)| planes.iter().any(|&(m, _)| m.dot(n) < -1.0 + 1e-12));
        if !flat {
            let along = along.normalize_or_zero();
            planes.retain(|&(n, _)| {
                let mut on = generators
                    .iter()
                    .chain(std::iter::once(&along))
                    .filter(|d| **d != DVec3::ZERO && n.dot(**d).abs() <= 1e-7);
                let Some(first) = on.next() else {
                    return false;
                };
                on.any(|d| first.cross(*d).length_squared() > 1e-14)
            });
        }
        let bound = RegionBound::from_planes(&planes);
        PLANES.set(planes);
        GENERATORS.set((buffer, tags));
        bound
    }

    /// A bound holding the regions of every edge inside the box
    /// `[lo, hi]` (a cluster of edges, for culling a tile against many
    /// edges at once): `conv(box) + cone{c_i − x_j}` over the box's
    /// corners `c_i` holds `a + t (a − x)` for every `a` in the box. Only
    /// valid planes are kept, not necessarily every facet (a looser bound
    /// is still conservative). For lights of at most four bounding
    /// corners (rects); otherwise no planes (the cost grows with the
    /// square of the corner count). `around_box_scalar` is its twin with
    /// the scalar facet test.
    pub fn around_box(lo: DVec3, hi: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        Self::box_bound(lo, hi, corners, slack, true)
    }

    /// [`RegionBound::around_box`] with the scalar facet test (its twin).
    #[cfg(test)]
    fn around_box_scalar(lo: DVec3, hi: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        Self::box_bound(lo, hi, corners, slack, false)
    }

    fn box_bound(lo: DVec3, hi: DVec3, corners: &[DVec3], slack: f64, simd: bool) -> RegionBound {
        if corners.len() > 4 || !(lo.cmple(hi).all()) {
            return RegionBound::default();
        }
        let points: [DVec3; 8] = std::array::from_fn(|k| {
            let pick = |b: usize, l: f64, h: f64| if k >> b & 1 == 1 { h } else { l };
            DVec3::new(
                pick(0, lo.x, hi.x),
                pick(1, lo.y, hi.y),
                pick(2, lo.z, hi.z),
            )
        });
        let (generators, tags) = cone_generators(&points, corners);
        let facets = FacetTest::new(&generators, simd);
        let mut planes: Vec<(DVec3, f64)> = Vec::new();
        let mut consider = |n: DVec3| {
            for n in facets.facets(n) {
                // Same tolerance as `new`; near-duplicate normals add
                // nothing but cost.
                if planes.iter().any(|&(m, _)| m.dot(n) > 1.0 - 1e-9) {
                    continue;
                }
                let h = points
                    .iter()
                    .map(|&c| n.dot(c))
                    .fold(f64::INFINITY, f64::min)
                    - slack;
                planes.push((n, h));
            }
        };
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        for x in axes {
            consider(x);
        }
        for (k, (&a, &ta)) in generators.iter().zip(&tags).enumerate() {
            for (&b, &tb) in generators[k + 1..].iter().zip(&tags[k + 1..]) {
                if may_span_facet(ta, tb) {
                    consider(a.cross(b));
                }
            }
            for x in axes {
                consider(x.cross(a));
            }
        }
        RegionBound::from_planes(&planes)
    }

    /// Also excludes receivers in front of both face planes or behind
    /// both (beyond `slack`): where the edge is not a silhouette, its
    /// multiplicity is 0 and it changes no counter.
    pub fn with_dihedral(mut self, faces: [(DVec3, f64); 2], slack: f64) -> RegionBound {
        self.dihedral4 = Some(Dihedral4::new(faces, slack));
        self
    }

    /// Whether the dihedral test excludes every point whose signed
    /// distances to the two face planes lie in `[lo0, hi0]`, `[lo1, hi1]`
    /// (the scalar twin of [`Dihedral4::excludes`]).
    #[cfg(test)]
    fn dihedral_excludes(&self, d: [(f64, f64); 2]) -> bool {
        match self.dihedral() {
            Some((_, slack)) => {
                let front = d.iter().all(|&(lo, _)| lo > slack);
                let behind = d.iter().all(|&(_, hi)| hi < -slack);
                front || behind
            }
            None => false,
        }
    }

    /// The receivers of `block` the region may hold, as a mask (bit `k`
    /// for receiver `k`): per receiver, not in front of both face planes
    /// or behind both (beyond the slack) and above every plane — the
    /// one-plane-at-a-time test of the tests' `excludes_point`, from the
    /// same operations in the same order, four receivers per vector, so
    /// one region's data serves sixteen receivers.
    #[inline(always)]
    pub fn admits(&self, block: &ReceiverBlock) -> u16 {
        admits_kernel!(f64x4, f64x4::splat, f64x4::new, self, block)
    }

    /// [`RegionBound::admits`] in AVX registers: the same kernel
    /// ([`admits_kernel!`]) on `simd::avx::F64x4`, the same operations per
    /// lane, so the same mask.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub fn admits_avx(&self, block: &ReceiverBlock) -> u16 {
        use crate::simd::avx::F64x4;
        admits_kernel!(F64x4, F64x4::splat, F64x4::new, self, block)
    }

    /// Whether `p` is outside the region, one plane at a time: the
    /// definition [`RegionBound::admits`] is tested against.
    #[cfg(test)]
    fn excludes_point(&self, p: DVec3) -> bool {
        if let Some((faces, _)) = self.dihedral() {
            let d = faces.map(|(n, h)| {
                let d = n.dot(p) - h;
                (d, d)
            });
            if self.dihedral_excludes(d) {
                return true;
            }
        }
        self.planes().any(|(n, h)| n.dot(p) < h)
    }

    /// Whether the whole box `[lo, hi]` is outside the region
    /// ([`excludes_box_kernel!`] on the facade's lanes).
    #[inline(always)]
    pub fn excludes_box(&self, lo: DVec3, hi: DVec3) -> bool {
        debug_assert!(lo.cmple(hi).all(), "box {lo} {hi}");
        excludes_box_kernel!(f64x4, f64x4::splat, f64x4::new, self, lo, hi)
    }

    /// [`RegionBound::excludes_box`] in AVX registers: the same kernel on
    /// `simd::avx::F64x4`, the same operations per lane, so the same
    /// verdict.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub fn excludes_box_avx(&self, lo: DVec3, hi: DVec3) -> bool {
        use crate::simd::avx::F64x4;
        debug_assert!(lo.cmple(hi).all(), "box {lo} {hi}");
        excludes_box_kernel!(F64x4, F64x4::splat, F64x4::new, self, lo, hi)
    }

    /// Of `items`, those whose region (`region_of`; `None`: left out
    /// without a test) does not exclude one of `boxes`, in order, into
    /// `out`: [`RegionBound::excludes_box`] over a list.
    #[inline(always)]
    pub fn keep_lanes<'r, T: Copy>(
        items: impl Iterator<Item = T>,
        region_of: impl Fn(T) -> Option<&'r RegionBound>,
        boxes: &ReceiverBoxes,
        out: &mut Vec<T>,
    ) {
        keep_kernel!(
            f64x4,
            f64x4::splat,
            f64x4::new,
            items,
            region_of,
            boxes,
            out
        )
    }

    /// [`RegionBound::keep_lanes`] in AVX registers, the kernel inlined
    /// in one loop (called box by box, the test was a tenth of a bunny
    /// profile in calls alone): the same verdicts.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub fn keep_avx<'r, T: Copy>(
        items: impl Iterator<Item = T>,
        region_of: impl Fn(T) -> Option<&'r RegionBound>,
        boxes: &ReceiverBoxes,
        out: &mut Vec<T>,
    ) {
        use crate::simd::avx::F64x4;
        keep_kernel!(
            F64x4,
            F64x4::splat,
            F64x4::new,
            items,
            region_of,
            boxes,
            out
        )
    }

    /// [`RegionBound::excludes_box`] one plane at a time (the scalar twin
    /// of the SoA test).
    #[cfg(test)]
    fn excludes_box_scalar(&self, lo: DVec3, hi: DVec3) -> bool {
        let far = |n: DVec3, up: bool| {
            let pick = |c: f64, l: f64, h: f64| if (c >= 0.0) == up { h } else { l };
            DVec3::new(
                pick(n.x, lo.x, hi.x),
                pick(n.y, lo.y, hi.y),
                pick(n.z, lo.z, hi.z),
            )
        };
        if let Some((faces, _)) = self.dihedral() {
            let d = faces.map(|(n, h)| (n.dot(far(n, false)) - h, n.dot(far(n, true)) - h));
            if self.dihedral_excludes(d) {
                return true;
            }
        }
        self.planes().any(|(n, h)| {
            // The box corner furthest along n.
            let far = DVec3::new(
                if n.x >= 0.0 { hi.x } else { lo.x },
                if n.y >= 0.0 { hi.y } else { lo.y },
                if n.z >= 0.0 { hi.z } else { lo.z },
            );
            n.dot(far) < h
        })
    }

    /// Bytes the bound holds: its own and its plane groups'.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<RegionBound>() + self.quads.capacity() * std::mem::size_of::<Planes4>()
    }

    /// Number of bounding planes (0: no rejection possible).
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there is no bounding plane.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [-1, 1).
    fn rng(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// The rect light most tests use: 2 × 2 at y = 5.
    const RECT: [DVec3; 4] = [
        DVec3::new(-1.0, 5.0, -1.0),
        DVec3::new(1.0, 5.0, -1.0),
        DVec3::new(1.0, 5.0, 1.0),
        DVec3::new(-1.0, 5.0, 1.0),
    ];

    /// Every point a light point sees through the edge, beyond it, is
    /// inside the bound; and the bound does reject far points.
    #[test]
    fn the_bound_holds_every_shadow_ray_and_rejects_others() {
        let corners = RECT;
        let mut s = 7u64;
        let mut rejected = 0;
        for _ in 0..200 {
            // An edge pointing roughly at the light (its line may pierce it).
            let v0 = DVec3::new(rng(&mut s), 1.5 + 0.5 * rng(&mut s), rng(&mut s));
            let v1 = v0 + DVec3::new(0.2 * rng(&mut s), 0.8, 0.2 * rng(&mut s));
            let bound = RegionBound::new(v0, v1, &corners, 0.0);
            for _ in 0..200 {
                let (a, b) = (0.5 * rng(&mut s) + 0.5, 0.5 * rng(&mut s) + 0.5);
                let x = corners[0]
                    .lerp(corners[1], a)
                    .lerp(corners[3].lerp(corners[2], a), b);
                let q = v0.lerp(v1, 0.5 * rng(&mut s) + 0.5);
                let t = 4.0 * (rng(&mut s) + 1.0);
                let p = q + (q - x) * t;
                // 1e-9 of slack for the rounding of p itself.
                let outside = bound
                    .planes()
                    .any(|(n, h)| n.dot(p) < h - 1e-9 * (1.0 + p.length()));
                assert!(!outside, "shadow ray point {p} rejected");
            }
            rejected += usize::from(bound.excludes_point(DVec3::new(20.0, 0.0, 0.0)));
            assert!(bound.excludes_point(v0 + DVec3::Y * 10.0) || bound.is_empty());
        }
        assert!(
            rejected > 150,
            "only {rejected} of 200 edges reject a far point"
        );
    }

    /// Two boxes hold every point, and appear where the points form two
    /// clusters far apart (a silhouette against the ground behind it),
    /// not on an even grid; an item is kept iff one box is not excluded.
    #[test]
    fn receiver_boxes_hold_every_point_and_split_only_across_a_gap() {
        let grid: Vec<DVec3> = (0..16)
            .map(|k| DVec3::new((k % 4) as f64 * 0.1, 0.0, (k / 4) as f64 * 0.1))
            .collect();
        let one = ReceiverBoxes::of(grid.iter().copied()).expect("points");
        assert_eq!(one.as_slice().len(), 1);
        let mut gapped = grid.clone();
        for p in &mut gapped[..5] {
            *p += DVec3::new(0.0, 3.0, 6.0);
        }
        let two = ReceiverBoxes::of(gapped.iter().copied()).expect("points");
        assert_eq!(two.as_slice().len(), 2);
        for p in &gapped {
            let inside = |&(lo, hi): &(DVec3, DVec3)| p.cmpge(lo).all() && p.cmple(hi).all();
            assert!(two.as_slice().iter().any(inside), "{p} outside");
        }
        assert!(ReceiverBoxes::of(std::iter::empty()).is_none());
        // A region that holds only the far cluster (above y = 1) is kept
        // by the two boxes, and one far below both is not.
        let up = RegionBound::from_planes(&[(DVec3::Y, 1.0)]);
        let down = RegionBound::from_planes(&[(-DVec3::Y, 10.0)]);
        let items = [(0, Some(&up)), (1, Some(&down)), (2, None)];
        let mut kept = Vec::new();
        RegionBound::keep_lanes(items.into_iter(), |(_, r)| r, &two, &mut kept);
        assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), [0]);
        let mut kept = Vec::new();
        RegionBound::keep_lanes(items.into_iter(), |(_, r)| r, &one, &mut kept);
        assert!(kept.is_empty());
    }

    /// A cluster's bound never rejects a shadow-ray point of an edge
    /// inside its box, and does reject far points.
    #[test]
    fn cluster_bound_holds_its_edges_regions() {
        let corners = RECT;
        let mut s = 11u64;
        let mut rejected = 0;
        for _ in 0..50 {
            let c = DVec3::new(
                2.0 * rng(&mut s),
                1.5 + 0.5 * rng(&mut s),
                2.0 * rng(&mut s),
            );
            let r = DVec3::new(0.3, 0.2, 0.3) * (1.0 + rng(&mut s));
            let (lo, hi) = (c - r, c + r);
            let bound = RegionBound::around_box(lo, hi, &corners, 0.0);
            for _ in 0..200 {
                let u = |s: &mut u64| 0.5 * rng(s) + 0.5;
                let a = lo + (hi - lo) * DVec3::new(u(&mut s), u(&mut s), u(&mut s));
                let x = corners[0]
                    .lerp(corners[1], u(&mut s))
                    .lerp(corners[3].lerp(corners[2], u(&mut s)), u(&mut s));
                let p = a + (a - x) * (4.0 * u(&mut s));
                let outside = bound
                    .planes()
                    .any(|(n, h)| n.dot(p) < h - 1e-9 * (1.0 + p.length()));
                assert!(!outside, "shadow ray point {p} of the box rejected");
            }
            rejected += usize::from(bound.excludes_point(c + DVec3::Y * 10.0));
        }
        assert!(
            rejected == 50,
            "only {rejected} of 50 boxes reject a point above"
        );
    }

    #[test]
    fn boxes_follow_points() {
        let corners = [DVec3::new(0.0, 5.0, 0.0), DVec3::new(1.0, 5.0, 0.0)];
        let b = RegionBound::new(DVec3::ZERO, DVec3::X, &corners, 0.0);
        assert!(!b.is_empty());
        let far = DVec3::new(0.0, 10.0, 0.0);
        assert!(b.excludes_point(far));
        assert!(b.excludes_box(far - 0.1, far + 0.1));
        // A box straddling the region is kept.
        assert!(!b.excludes_box(DVec3::new(-5.0, -5.0, -5.0), DVec3::new(5.0, 5.0, 5.0)));
        // Degenerate edges and lights: no panic, no planes that reject the
        // points on the edge itself.
        let d = RegionBound::new(DVec3::ZERO, DVec3::ZERO, &[DVec3::ZERO], 0.0);
        assert!(!d.excludes_point(DVec3::ZERO));
    }

    /// The dihedral test drops points in front of both faces or behind
    /// both, keeps points where they disagree, and boxes follow points.
    #[test]
    fn dihedral_keeps_only_silhouette_sides() {
        let corners = [DVec3::new(-1.0, 5.0, -1.0), DVec3::new(1.0, 5.0, 1.0)];
        // Edge along x at the origin; faces with normals +y+z and +y-z.
        let (n0, n1) = (
            DVec3::new(0.0, 1.0, 1.0).normalize(),
            DVec3::new(0.0, 1.0, -1.0).normalize(),
        );
        let b = RegionBound::new(DVec3::ZERO, DVec3::X, &corners, 0.0)
            .with_dihedral([(n0, 0.0), (n1, 0.0)], 1e-9);
        // Below the edge, between the planes' negative sides: behind both.
        assert!(b.excludes_point(DVec3::new(0.5, -3.0, 0.0)));
        // Off to the side: in front of one, behind the other — kept
        // unless the cone excludes it.
        let side = DVec3::new(0.5, -1.0, 2.0);
        assert!(n0.dot(side) > 0.0 && n1.dot(side) < 0.0);
        let plain = RegionBound::new(DVec3::ZERO, DVec3::X, &corners, 0.0);
        assert_eq!(b.excludes_point(side), plain.excludes_point(side));
        // A box straddling both planes is kept by the dihedral test.
        let big = RegionBound::default().with_dihedral([(n0, 0.0), (n1, 0.0)], 1e-9);
        assert!(!big.excludes_box(DVec3::splat(-1.0), DVec3::splat(1.0)));
        assert!(big.excludes_box(DVec3::new(0.0, -5.0, -0.1), DVec3::new(1.0, -4.0, 0.1)));
    }

    /// The SoA tests decide exactly as their scalar twins, box by box and
    /// point by point: random edges, clusters and dihedral bounds, random
    /// and degenerate boxes (flat, a point, straddling zero with ±0
    /// corners) and planes with zero normal components (axis-aligned
    /// normals of `around_box`).
    #[test]
    fn soa_tests_match_the_scalar_twins() {
        let corners = RECT;
        let mut s = 23u64;
        let (mut checked, mut excluded, mut admitted) = (0usize, 0usize, 0usize);
        for round in 0..300 {
            let v0 = DVec3::new(rng(&mut s), 1.5 + 0.5 * rng(&mut s), rng(&mut s));
            let v1 = v0 + DVec3::new(0.3 * rng(&mut s), 0.8 * rng(&mut s), 0.3 * rng(&mut s));
            let mut bound = match round % 3 {
                0 => RegionBound::new(v0, v1, &corners, 0.0),
                1 => RegionBound::around_box(v0.min(v1), v0.max(v1), &corners, 1e-6),
                _ => {
                    let n0 = DVec3::new(rng(&mut s), 1.0, rng(&mut s)).normalize();
                    let n1 = DVec3::new(rng(&mut s), 1.0, rng(&mut s)).normalize();
                    RegionBound::new(v0, v1, &corners, 1e-6)
                        .with_dihedral([(n0, n0.dot(v0)), (n1, n1.dot(v0))], 1e-9)
                }
            };
            if round % 7 == 0 {
                // Zero and negative-zero normal components.
                bound = RegionBound::from_planes(&[
                    (DVec3::new(0.0, 1.0, -0.0), 0.5),
                    (DVec3::new(-0.0, -0.0, -1.0), -0.25),
                    (DVec3::new(0.6, -0.0, 0.8), rng(&mut s)),
                ])
                .with_dihedral(
                    [
                        (DVec3::new(0.0, 1.0, -0.0), 0.1 * rng(&mut s)),
                        (DVec3::new(-0.0, 0.6, -0.8), 0.1 * rng(&mut s)),
                    ],
                    1e-9,
                );
            }
            assert_eq!(bound.quads.len(), bound.len().div_ceil(4));
            for k in 0..200 {
                let c = DVec3::new(4.0 * rng(&mut s), 3.0 * rng(&mut s), 4.0 * rng(&mut s));
                let r = DVec3::new(rng(&mut s), rng(&mut s), rng(&mut s)).abs();
                let (lo, hi) = match k % 5 {
                    0 => (c, c),
                    1 => (DVec3::new(c.x, -0.0, c.z), DVec3::new(c.x + r.x, 0.0, c.z)),
                    2 => (-r, r),
                    _ => (c - r, c + r),
                };
                let got = bound.excludes_box(lo, hi);
                assert_eq!(got, bound.excludes_box_scalar(lo, hi), "box {lo} {hi}");
                let mut kept = Vec::new();
                let items = [(0, Some(&bound)), (1, None), (2, Some(&bound))];
                let boxes = ReceiverBoxes::single(lo, hi);
                RegionBound::keep_lanes(items.into_iter(), |(_, r)| r, &boxes, &mut kept);
                let want: Vec<usize> = if got { vec![] } else { vec![0, 2] };
                assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), want);
                #[cfg(target_arch = "x86_64")]
                if crate::simd::avx::available() {
                    // SAFETY: the CPU has AVX (checked).
                    let avx = unsafe { bound.excludes_box_avx(lo, hi) };
                    assert_eq!(avx, got, "AVX box {lo} {hi}");
                    let mut kept = Vec::new();
                    // SAFETY: the CPU has AVX (checked).
                    unsafe {
                        RegionBound::keep_avx(items.into_iter(), |(_, r)| r, &boxes, &mut kept)
                    };
                    assert_eq!(
                        kept.iter().map(|k| k.0).collect::<Vec<_>>(),
                        want,
                        "AVX keep"
                    );
                }
                // Sixteen receivers around `c`, some missing.
                let points: [Option<DVec3>; 16] = std::array::from_fn(|j| {
                    let q =
                        c + DVec3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * (0.1 * j as f64);
                    (j % 5 != 3).then_some(q)
                });
                let block = ReceiverBlock::new(&points);
                let mask = bound.admits(&block);
                #[cfg(target_arch = "x86_64")]
                if crate::simd::avx::available() {
                    // SAFETY: the CPU has AVX (checked).
                    assert_eq!(unsafe { bound.admits_avx(&block) }, mask, "AVX admits");
                }
                for (j, q) in points.iter().enumerate() {
                    let want = q.is_some_and(|q| !bound.excludes_point(q));
                    assert_eq!(mask >> j & 1 == 1, want, "receiver {j} {q:?}");
                    admitted += usize::from(want);
                }
                checked += 1;
                excluded += usize::from(got);
            }
        }
        assert!(
            excluded > checked / 10 && excluded < checked,
            "{excluded} of {checked}"
        );
        assert!(
            admitted > 10_000 && admitted < 12 * checked,
            "{admitted} of {} receivers",
            16 * checked
        );
    }

    /// The fast constructors give the scalar twins' planes, in the same
    /// order, bit for bit: random edges (some pointing at the light),
    /// degenerate ones, and random clusters, against rect and other
    /// lights.
    #[test]
    fn constructors_match_the_scalar_twins() {
        let bits = |b: &RegionBound| -> Vec<[u64; 4]> {
            b.planes()
                .map(|(n, h)| [n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), h.to_bits()])
                .collect()
        };
        let rect = RECT;
        let tilted: Vec<DVec3> = rect
            .iter()
            .map(|c| *c + DVec3::new(0.0, 0.3 * c.x, 0.0))
            .collect();
        let lights: [&[DVec3]; 4] = [&rect, &tilted, &rect[..2], &rect[..1]];
        let mut s = 31u64;
        let mut planes = 0;
        for round in 0..400 {
            let corners = lights[round % lights.len()];
            let v0 = DVec3::new(rng(&mut s), 1.5 + 0.5 * rng(&mut s), rng(&mut s));
            let v1 = match round % 5 {
                0 => v0,
                1 => v0 + DVec3::Y,
                _ => v0 + DVec3::new(0.3 * rng(&mut s), 0.8 * rng(&mut s), 0.3 * rng(&mut s)),
            };
            let slack = if round % 2 == 0 { 0.0 } else { 1e-6 };
            let fast = RegionBound::new(v0, v1, corners, slack);
            assert_eq!(
                bits(&fast),
                bits(&RegionBound::new_scalar(v0, v1, corners, slack))
            );
            planes += fast.len();
            let (lo, hi) = (
                v0.min(v1),
                v0.max(v1) + DVec3::splat(0.1 * (round % 3) as f64),
            );
            let fast = RegionBound::around_box(lo, hi, corners, slack);
            let twin = RegionBound::around_box_scalar(lo, hi, corners, slack);
            assert_eq!(bits(&fast), bits(&twin), "round {round}");
            planes += fast.len();
        }
        assert!(planes > 4000, "{planes} planes");
    }

    /// The planes and the dihedral faces are stored once, in their SoA
    /// lanes; reading them back gives the values built, bit for bit and
    /// in order, for every plane count (partial last groups included).
    #[test]
    fn planes_and_faces_read_back_as_built() {
        let bits = |(n, h): (DVec3, f64)| [n.x, n.y, n.z, h].map(f64::to_bits);
        let mut s = 5u64;
        for count in 0..10 {
            let planes: Vec<(DVec3, f64)> = (0..count)
                .map(|_| {
                    let n = DVec3::new(rng(&mut s), rng(&mut s), -0.0 * rng(&mut s));
                    (n, rng(&mut s))
                })
                .collect();
            let faces = [
                (DVec3::new(rng(&mut s), -0.0, 1.0), rng(&mut s)),
                (DVec3::X, -0.0),
            ];
            let bound = RegionBound::from_planes(&planes).with_dihedral(faces, 1e-7);
            assert_eq!(bound.len(), count);
            let back: Vec<_> = bound.planes().map(bits).collect();
            assert_eq!(back, planes.iter().map(|&p| bits(p)).collect::<Vec<_>>());
            let (read, slack) = bound.dihedral().expect("faces set");
            assert_eq!(read.map(bits), faces.map(bits));
            assert_eq!(slack.to_bits(), 1e-7f64.to_bits());
        }
    }
}
