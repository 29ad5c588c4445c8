//! Penumbra volumes from separating planes (§3.2), hard shadow volumes
//! per light sample (4 planes), box-vs-volume and point-in-volume tests.
//!
//! Everything is in `f64`, relative to the light's centre (differences
//! of `f32` inputs, exact). Penumbra-volume planes are unit-normalised so
//! a point's value is a distance, and a point counts as inside when its
//! value is `≥ −slack` (`slack` far above the planes' rounding, far below
//! the tie distance): the culling is conservative with respect to the
//! exact per-sample test, so the basic and every optimised traversal
//! find the same blocked relations. The value of a plane is evaluated as
//! `((nx x + ny y) + nz z) + d` everywhere: each rounding is monotonic in
//! each coordinate, so a box whose "negative" corner is inside holds only
//! inside points (the active-plane-set rule gives the point test's
//! answer, bit for bit).

use crate::simd::f64x4;
use glam::DVec3;

/// A convex light part as a box in the light's frame: its 8 corners,
/// relative to the light's centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightBox {
    /// Corners `lo + (i&1, i&2, i&4)·(hi − lo)` in world axes.
    pub corners: [DVec3; 8],
}

/// Most planes kept per penumbra volume (a `u32` active set); further
/// separating planes are dropped, which only loosens the volume.
pub const MAX_PLANES: usize = 32;

/// A plane `n·x + d`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Plane {
    /// Normal.
    pub n: [f64; 3],
    /// Offset.
    pub d: f64,
}

impl Plane {
    /// The plane's value at `p`, in the one evaluation order.
    #[inline(always)]
    pub fn eval(&self, p: [f64; 3]) -> f64 {
        ((self.n[0] * p[0] + self.n[1] * p[1]) + self.n[2] * p[2]) + self.d
    }

    /// The value at the corner of box `[lo, hi]` where it is least.
    #[inline(always)]
    fn box_min(&self, lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
        let c = |i: usize| if self.n[i] >= 0.0 { lo[i] } else { hi[i] };
        self.eval([c(0), c(1), c(2)])
    }

    /// The value at the corner where it is largest.
    #[inline(always)]
    fn box_max(&self, lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
        let c = |i: usize| if self.n[i] >= 0.0 { hi[i] } else { lo[i] };
        self.eval([c(0), c(1), c(2)])
    }
}

/// A penumbra volume: the intersection of the inner sides of its planes
/// (no planes: all of space).
#[derive(Debug, Clone, Default)]
pub struct PenumbraVolume {
    /// The planes (unit normals), at most [`MAX_PLANES`].
    pub planes: Vec<Plane>,
    /// The planes four by four as lanes (padding lanes zero, never
    /// active), filled by [`PenumbraVolume::finish`]; the SIMD tests use
    /// them while they match `planes`.
    quads: Vec<PlaneQuad>,
}

/// Four planes as lanes (plain arrays, so that the facade's lanes and
/// AVX registers load them alike).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
struct PlaneQuad {
    nx: [f64; 4],
    ny: [f64; 4],
    nz: [f64; 4],
    d: [f64; 4],
}

/// [`PenumbraVolume::test_box`]'s kernel over `$lane` lanes (made by
/// `$splat(v)` and `$load(&[f64; 4])`), in names both the facade's
/// `f64x4` and `simd::avx::F64x4` have: the same operations per lane, so
/// the same answer on each.
macro_rules! test_box_kernel {
    ($lane:ty, $splat:path, $load:path, $v:expr, $lo:expr, $hi:expr, $active:expr, $slack:expr, $prune:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul};
        let (v, lo, hi, active): (&PenumbraVolume, &[f64; 3], &[f64; 3], u32) =
            ($v, $lo, $hi, $active);
        let zero = $splat(0.0);
        let s = $splat(-$slack);
        let (lx, ly, lz): ($lane, $lane, $lane) = ($splat(lo[0]), $splat(lo[1]), $splat(lo[2]));
        let (hx, hy, hz): ($lane, $lane, $lane) = ($splat(hi[0]), $splat(hi[1]), $splat(hi[2]));
        let mut out = active;
        let mut outside = false;
        for (i, q) in v.quads.iter().enumerate() {
            let lanes = (active >> (4 * i)) & 0xf;
            if lanes == 0 {
                continue;
            }
            let (nx, ny, nz, d): ($lane, $lane, $lane, $lane) =
                ($load(&q.nx), $load(&q.ny), $load(&q.nz), $load(&q.d));
            let (px, py, pz) = (nx.cmp_ge(zero), ny.cmp_ge(zero), nz.cmp_ge(zero));
            // The corner where the value is largest: hi where n ≥ 0.
            let vmax = nx
                .mul(px.blend(hx, lx))
                .add(ny.mul(py.blend(hy, ly)))
                .add(nz.mul(pz.blend(hz, lz)))
                .add(d);
            if vmax.cmp_lt(s).move_mask() & lanes != 0 {
                outside = true;
                break;
            }
            if $prune {
                let vmin = nx
                    .mul(px.blend(lx, hx))
                    .add(ny.mul(py.blend(ly, hy)))
                    .add(nz.mul(pz.blend(lz, hz)))
                    .add(d);
                out &= !((vmin.cmp_ge(s).move_mask() & lanes) << (4 * i));
            }
        }
        if outside {
            BoxTest::Outside
        } else {
            BoxTest::Active(out)
        }
    }};
}

/// [`PenumbraVolume::contains`]'s kernel over `$lane` lanes, as
/// [`test_box_kernel!`].
macro_rules! contains_kernel {
    ($lane:ty, $splat:path, $load:path, $v:expr, $p:expr, $active:expr, $slack:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul};
        let (v, p, active): (&PenumbraVolume, [f64; 3], u32) = ($v, $p, $active);
        let s = $splat(-$slack);
        let (x, y, z): ($lane, $lane, $lane) = ($splat(p[0]), $splat(p[1]), $splat(p[2]));
        let mut inside = true;
        for (i, q) in v.quads.iter().enumerate() {
            let lanes = (active >> (4 * i)) & 0xf;
            if lanes == 0 {
                continue;
            }
            let value = $load(&q.nx)
                .mul(x)
                .add($load(&q.ny).mul(y))
                .add($load(&q.nz).mul(z))
                .add($load(&q.d));
            if value.cmp_lt(s).move_mask() & lanes != 0 {
                inside = false;
                break;
            }
        }
        inside
    }};
}

/// A box against a volume's active planes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxTest {
    /// Entirely outside one plane.
    Outside,
    /// Overlapping; the planes the box is not entirely inside of.
    Active(u32),
}

impl PenumbraVolume {
    /// Bytes it holds (itself and its plane lists).
    pub fn bytes(&self) -> u64 {
        (std::mem::size_of::<Self>()
            + self.planes.capacity() * std::mem::size_of::<Plane>()
            + self.quads.capacity() * std::mem::size_of::<PlaneQuad>()) as u64
    }

    /// Every plane active.
    pub fn all(&self) -> u32 {
        if self.planes.len() >= 32 {
            u32::MAX
        } else {
            (1u32 << self.planes.len()) - 1
        }
    }

    /// Fills the lanes the SIMD tests read from `planes` (after any
    /// change to them).
    pub fn finish(&mut self) {
        self.quads.clear();
        for c in self.planes.chunks(4) {
            let mut a = [[0.0f64; 4]; 4];
            for (j, p) in c.iter().enumerate() {
                a[0][j] = p.n[0];
                a[1][j] = p.n[1];
                a[2][j] = p.n[2];
                a[3][j] = p.d;
            }
            self.quads.push(PlaneQuad {
                nx: a[0],
                ny: a[1],
                nz: a[2],
                d: a[3],
            });
        }
    }

    /// Whether the lanes match the planes (else the scalar tests run).
    #[inline(always)]
    fn has_quads(&self) -> bool {
        self.quads.len() == self.planes.len().div_ceil(4)
    }

    /// The box `[lo, hi]` against the `active` planes; with `prune`, the
    /// planes it is entirely inside of leave the active set (§3.3 B).
    /// Four planes at a time through the SIMD facade, each plane's value
    /// at each corner computed as [`Plane::eval`] does: the answer is
    /// [`PenumbraVolume::test_box_scalar`]'s, bit for bit.
    #[inline]
    pub fn test_box(
        &self,
        lo: &[f64; 3],
        hi: &[f64; 3],
        active: u32,
        slack: f64,
        prune: bool,
    ) -> BoxTest {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx::available() {
            // SAFETY: `available` checked that the CPU has AVX, the one
            // requirement of `test_box_avx`.
            return unsafe { self.test_box_avx(lo, hi, active, slack, prune) };
        }
        self.test_box_lanes(lo, hi, active, slack, prune)
    }

    /// [`PenumbraVolume::test_box`] on the facade's lanes.
    #[inline]
    pub fn test_box_lanes(
        &self,
        lo: &[f64; 3],
        hi: &[f64; 3],
        active: u32,
        slack: f64,
        prune: bool,
    ) -> BoxTest {
        if !self.has_quads() {
            return self.test_box_scalar(lo, hi, active, slack, prune);
        }
        let load = |a: &[f64; 4]| f64x4::new(*a);
        test_box_kernel!(
            f64x4,
            f64x4::splat,
            load,
            self,
            lo,
            hi,
            active,
            slack,
            prune
        )
    }

    /// [`PenumbraVolume::test_box`] in AVX registers: the same kernel, the
    /// same answer.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub fn test_box_avx(
        &self,
        lo: &[f64; 3],
        hi: &[f64; 3],
        active: u32,
        slack: f64,
        prune: bool,
    ) -> BoxTest {
        use crate::simd::avx::F64x4;
        if !self.has_quads() {
            return self.test_box_scalar(lo, hi, active, slack, prune);
        }
        test_box_kernel!(
            F64x4,
            F64x4::splat,
            F64x4::load,
            self,
            lo,
            hi,
            active,
            slack,
            prune
        )
    }

    /// [`PenumbraVolume::test_box`], plane by plane (its scalar twin).
    #[inline]
    pub fn test_box_scalar(
        &self,
        lo: &[f64; 3],
        hi: &[f64; 3],
        active: u32,
        slack: f64,
        prune: bool,
    ) -> BoxTest {
        let mut out = active;
        let mut bits = active;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let p = &self.planes[i];
            if p.box_max(lo, hi) < -slack {
                return BoxTest::Outside;
            }
            if prune && p.box_min(lo, hi) >= -slack {
                out &= !(1 << i);
            }
        }
        BoxTest::Active(out)
    }

    /// Whether `p` is inside every `active` plane: four planes at a time
    /// through the SIMD facade, each value [`Plane::eval`]'s (the answer
    /// is [`PenumbraVolume::contains_scalar`]'s).
    #[inline]
    pub fn contains(&self, p: [f64; 3], active: u32, slack: f64) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx::available() {
            // SAFETY: `available` checked that the CPU has AVX, the one
            // requirement of `contains_avx`.
            return unsafe { self.contains_avx(p, active, slack) };
        }
        self.contains_lanes(p, active, slack)
    }

    /// [`PenumbraVolume::contains`] on the facade's lanes.
    #[inline]
    pub fn contains_lanes(&self, p: [f64; 3], active: u32, slack: f64) -> bool {
        if !self.has_quads() {
            return self.contains_scalar(p, active, slack);
        }
        let load = |a: &[f64; 4]| f64x4::new(*a);
        contains_kernel!(f64x4, f64x4::splat, load, self, p, active, slack)
    }

    /// [`PenumbraVolume::contains`] in AVX registers: the same kernel, the
    /// same answer.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub fn contains_avx(&self, p: [f64; 3], active: u32, slack: f64) -> bool {
        use crate::simd::avx::F64x4;
        if !self.has_quads() {
            return self.contains_scalar(p, active, slack);
        }
        contains_kernel!(F64x4, F64x4::splat, F64x4::load, self, p, active, slack)
    }

    /// [`PenumbraVolume::contains`], plane by plane (its scalar twin).
    #[inline]
    pub fn contains_scalar(&self, p: [f64; 3], active: u32, slack: f64) -> bool {
        let mut bits = active;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if self.planes[i].eval(p) < -slack {
                return false;
            }
        }
        true
    }
}

fn cross(a: DVec3, b: DVec3) -> DVec3 {
    a.cross(b)
}

/// The penumbra volume of light part `light` and triangle `t` (relative
/// to the light's centre): every separating plane through an edge of one
/// and a vertex of the other with all of the light part on one side and
/// all of the triangle on the other, oriented so the triangle's side is
/// inside, plus the triangle's plane when the light part lies strictly on
/// one side of it (§3.2). `tol` is the relative tolerance for a vertex
/// "on" a candidate plane.
pub fn penumbra_volume(light: &LightBox, t: &[DVec3; 3], out: &mut PenumbraVolume) {
    out.planes.clear();
    // Stale lanes must never pass `has_quads` (same chunk count, old
    // planes): the SIMD tests read lanes only after `finish` refills them.
    out.quads.clear();
    let lv = &light.corners;
    // The box's 12 edges: corner pairs differing in one bit.
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    // Each vertex's largest coordinate magnitude, once (the candidates'
    // scales are maxima of three of them).
    let lm = lv.map(|c| c.abs().max_element());
    let tm = t.map(|c| c.abs().max_element());
    let consider = |p: DVec3, q: DVec3, w: DVec3, sm: f64, out: &mut PenumbraVolume| {
        let n = cross(q - p, w - p);
        let len = n.length();
        if !(len > 0.0) || !len.is_finite() {
            return;
        }
        let scale = sm;
        // A vertex within this of the plane counts as on it (the plane's
        // own vertices compute to rounding noise, not to 0).
        let tol = 1e-12 * scale * len;
        let val = |c: &DVec3| n.dot(*c - p);
        // The triangle's side first (3 values), then the light's corners
        // with an early exit: most candidates fail on the first corners.
        // (Compares rather than f64::min / max: the same results for
        // every value, NaN included, in fewer instructions.)
        let (mut tmin, mut tmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for c in t {
            let v = val(c);
            if v < tmin {
                tmin = v;
            }
            if v > tmax {
                tmax = v;
            }
        }
        let sign = if tmin >= -tol {
            1.0
        } else if tmax <= tol {
            -1.0
        } else {
            return;
        };
        let mut lspread = (f64::INFINITY, f64::NEG_INFINITY);
        for c in lv {
            let v = sign * val(c);
            if v > tol {
                return;
            }
            if v < lspread.0 {
                lspread.0 = v;
            }
            if v > lspread.1 {
                lspread.1 = v;
            }
        }
        // A plane with both sides "on" it separates nothing.
        if (lspread.1 - lspread.0) <= tol && (tmax - tmin) <= tol {
            return;
        }
        let n = n * (sign / len);
        let plane = Plane {
            n: [n.x, n.y, n.z],
            d: -n.dot(p),
        };
        // Near-duplicates (a thin light box gives each plane twice, through
        // its top and its bottom edge) are dropped: dropping a plane only
        // widens the volume, so this stays conservative.
        let dup = out.planes.iter().any(|q| {
            let c = q.n[0] * plane.n[0] + q.n[1] * plane.n[1] + q.n[2] * plane.n[2];
            c > 1.0 - 1e-9
        });
        if out.planes.len() < MAX_PLANES && !dup {
            out.planes.push(plane);
        }
    };
    // The box's edges across its thickness only matter for a thick box
    // (a volumetric light part); skipping candidates is conservative.
    let thick =
        (lv[4] - lv[0]).length() > 1e-9 * (lv[1] - lv[0]).length().max((lv[2] - lv[0]).length());
    let edges = if thick { &EDGES[..] } else { &EDGES[..8] };
    for &(i, j) in edges {
        for (&w, &wm) in t.iter().zip(&tm) {
            consider(lv[i], lv[j], w, lm[i].max(lm[j]).max(wm), out);
        }
    }
    for e in 0..3 {
        let (a, b) = (e, (e + 1) % 3);
        for (&w, &wm) in lv.iter().zip(&lm) {
            consider(t[a], t[b], w, tm[a].max(tm[b]).max(wm), out);
        }
    }
    // The cap: the triangle's own plane, when the light part is strictly
    // on one side of it.
    let n = cross(t[1] - t[0], t[2] - t[0]);
    let len = n.length();
    if len > 0.0 && len.is_finite() && out.planes.len() < MAX_PLANES {
        let n = n / len;
        let d = -n.dot(t[0]);
        let side = lv.map(|c| n.dot(c) + d);
        if side.iter().all(|&s| s > 0.0) {
            out.planes.push(Plane {
                n: [-n.x, -n.y, -n.z],
                d: -d,
            });
        } else if side.iter().all(|&s| s < 0.0) {
            out.planes.push(Plane {
                n: [n.x, n.y, n.z],
                d,
            });
        }
    }
    out.finish();
}

/// The hard shadow volumes of one group of samples (at most 32) and one
/// triangle, as structure-of-arrays lanes: plane `q` of sample `j` is
/// `(nx[q][j], ny[q][j], nz[q][j], d[q][j])`, inside iff its value is
/// `> 0`; an empty volume (sample in the triangle's plane, degenerate
/// triangle) has a plane that is never positive.
#[derive(Debug, Clone)]
pub struct HardVolumes {
    /// Per plane (3 edges, then the triangle's plane): normal x per sample.
    pub nx: [[f64; 32]; 4],
    /// Normal y.
    pub ny: [[f64; 32]; 4],
    /// Normal z.
    pub nz: [[f64; 32]; 4],
    /// Offset.
    pub d: [[f64; 32]; 4],
    /// Samples in the group.
    pub len: usize,
}

impl Default for HardVolumes {
    fn default() -> Self {
        HardVolumes {
            nx: [[0.0; 32]; 4],
            ny: [[0.0; 32]; 4],
            nz: [[0.0; 32]; 4],
            d: [[-1.0; 32]; 4],
            len: 0,
        }
    }
}

impl HardVolumes {
    /// Builds the volumes of `samples` (≤ 32) and triangle `t` (§3.2:
    /// three planes through the sample and an edge, and the triangle's
    /// plane): a point `o` is inside iff the open segment from `o` to the
    /// sample crosses the triangle's interior. Four samples at a time
    /// through the SIMD facade (IEEE operations only, so the bits are the
    /// scalar formula's, [`HardVolumes::build_scalar`]).
    pub fn build(&mut self, samples: &GroupSoa, t: &[DVec3; 3]) {
        self.build_chunks(samples, t, 0xff);
    }

    /// [`HardVolumes::build`] for the chunks of four samples in `chunks`
    /// (bit `c`: samples `4c .. 4c + 4`) only; the others keep their
    /// values (the caller tracks which chunks are current).
    pub fn build_chunks(&mut self, samples: &GroupSoa, t: &[DVec3; 3], chunks: u8) {
        use crate::simd::f64x4;
        self.len = samples.len;
        let nt = cross(t[1] - t[0], t[2] - t[0]);
        let sp = |v: f64| f64x4::splat(v);
        let zero = f64x4::ZERO;
        let (t0, t1, t2) = (t[0], t[1], t[2]);
        let count = samples.len.div_ceil(4);
        for c in 0..count {
            if (chunks >> c) & 1 == 0 {
                continue;
            }
            let r = 4 * c..4 * c + 4;
            let x = f64x4::load(&samples.x[r.clone()]);
            let y = f64x4::load(&samples.y[r.clone()]);
            let z = f64x4::load(&samples.z[r.clone()]);
            let sub = |p: DVec3| (sp(p.x) - x, sp(p.y) - y, sp(p.z) - z);
            let (a, b, cc) = (sub(t0), sub(t1), sub(t2));
            type V = (f64x4, f64x4, f64x4);
            let cr = |p: V, q: V| -> V {
                (
                    p.1 * q.2 - p.2 * q.1,
                    p.2 * q.0 - p.0 * q.2,
                    p.0 * q.1 - p.1 * q.0,
                )
            };
            let dot = |p: V, q: V| (p.0 * q.0 + p.1 * q.1) + p.2 * q.2;
            let bc = cr(b, cc);
            let det = dot(a, bc);
            // side = nt · (x − t0) = −nt · a.
            let side = zero - ((sp(nt.x) * a.0 + sp(nt.y) * a.1) + sp(nt.z) * a.2);
            // Empty: det or side 0, or det not finite (the abs compare is
            // false for NaN and infinity).
            let finite = det.abs().cmp_lt(sp(f64::INFINITY));
            let empty = finite.blend(det.cmp_eq(zero) | side.cmp_eq(zero), zero.cmp_eq(zero));
            let flip = det.cmp_lt(zero);
            let pos = (x, y, z);
            let lanes = c * 4;
            for (q, (p, w)) in [(a, b), (b, cc), (cc, a)].into_iter().enumerate() {
                let n = cr(p, w);
                let n = (
                    flip.blend(zero - n.0, n.0),
                    flip.blend(zero - n.1, n.1),
                    flip.blend(zero - n.2, n.2),
                );
                let d = zero - dot(n, pos);
                self.store(q, lanes, empty, n, d);
            }
            // The triangle's plane, inside away from the sample: −sign(side)·nt.
            let away = side.cmp_gt(zero);
            let n4 = (
                away.blend(sp(-nt.x), sp(nt.x)),
                away.blend(sp(-nt.y), sp(nt.y)),
                away.blend(sp(-nt.z), sp(nt.z)),
            );
            let d4 = zero - ((n4.0 * sp(t0.x) + n4.1 * sp(t0.y)) + n4.2 * sp(t0.z));
            self.store(3, lanes, empty, n4, d4);
        }
        for j in samples.len..32 {
            for q in 0..4 {
                self.set(q, j, DVec3::ZERO, -1.0);
            }
        }
    }

    #[inline(always)]
    fn store(
        &mut self,
        q: usize,
        lanes: usize,
        empty: crate::simd::f64x4,
        n: (crate::simd::f64x4, crate::simd::f64x4, crate::simd::f64x4),
        d: crate::simd::f64x4,
    ) {
        use crate::simd::f64x4;
        let zero = f64x4::ZERO;
        let (nx, ny, nz) = (
            empty.blend(zero, n.0).to_array(),
            empty.blend(zero, n.1).to_array(),
            empty.blend(zero, n.2).to_array(),
        );
        let d = empty.blend(f64x4::splat(-1.0), d).to_array();
        self.nx[q][lanes..lanes + 4].copy_from_slice(&nx);
        self.ny[q][lanes..lanes + 4].copy_from_slice(&ny);
        self.nz[q][lanes..lanes + 4].copy_from_slice(&nz);
        self.d[q][lanes..lanes + 4].copy_from_slice(&d);
    }

    /// The scalar formula of [`HardVolumes::build`], for checking it.
    pub fn build_scalar(&mut self, samples: &[DVec3], t: &[DVec3; 3]) {
        self.len = samples.len();
        let nt = cross(t[1] - t[0], t[2] - t[0]);
        for (j, &x) in samples.iter().enumerate() {
            let (a, b, c) = (t[0] - x, t[1] - x, t[2] - x);
            let det = a.dot(cross(b, c));
            let side = -nt.dot(a);
            if det == 0.0 || side == 0.0 || !det.is_finite() {
                for q in 0..4 {
                    self.set(q, j, DVec3::ZERO, -1.0);
                }
                continue;
            }
            let flip = det < 0.0;
            for (q, (p, r)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
                let n = cross(p, r);
                let n = if flip { -n } else { n };
                self.set(q, j, n, -n.dot(x));
            }
            let n4 = if side > 0.0 { -nt } else { nt };
            self.set(3, j, n4, -n4.dot(t[0]));
        }
        for j in samples.len()..32 {
            for q in 0..4 {
                self.set(q, j, DVec3::ZERO, -1.0);
            }
        }
    }

    #[inline(always)]
    fn set(&mut self, q: usize, j: usize, n: DVec3, d: f64) {
        self.nx[q][j] = n.x;
        self.ny[q][j] = n.y;
        self.nz[q][j] = n.z;
        self.d[q][j] = d;
    }
}

/// The boxes of a group's samples four by four (the kernel's lanes):
/// chunk `c` bounds samples `4c .. 4c + 4` (exact `f64` positions).
#[derive(Debug, Clone)]
pub struct ChunkBoxes {
    /// Least corner per chunk, per axis.
    pub lo: [[f64; 8]; 3],
    /// Greatest corner per chunk, per axis.
    pub hi: [[f64; 8]; 3],
    /// Least corner of the whole group (of every chunk's box).
    pub group_lo: [f64; 3],
    /// Greatest corner of the whole group.
    pub group_hi: [f64; 3],
}

impl ChunkBoxes {
    /// The boxes of `samples` (≤ 32); chunks without samples are empty
    /// (`lo = +∞`, `hi = −∞`: no plane's maximum over them is finite).
    pub fn new(samples: &[DVec3]) -> ChunkBoxes {
        let mut b = ChunkBoxes {
            lo: [[f64::INFINITY; 8]; 3],
            hi: [[f64::NEG_INFINITY; 8]; 3],
            group_lo: [f64::INFINITY; 3],
            group_hi: [f64::NEG_INFINITY; 3],
        };
        for (j, p) in samples.iter().enumerate() {
            for (a, v) in p.to_array().into_iter().enumerate() {
                b.lo[a][j / 4] = b.lo[a][j / 4].min(v);
                b.hi[a][j / 4] = b.hi[a][j / 4].max(v);
                b.group_lo[a] = b.group_lo[a].min(v);
                b.group_hi[a] = b.group_hi[a].max(v);
            }
        }
        b
    }
}

/// Relative rounding allowance of the cone prefilter: `CONE_C · ε · M³`
/// bounds, with a wide margin, the rounding of both the kernel's plane
/// values (≈ 400 ε M³) and the cone's own (the same form), for
/// coordinates of magnitude at most `M`.
const CONE_C: f64 = 4096.0 * f64::EPSILON;

/// [`Cone::outside_chunks`] over `$lane` lanes (as
/// [`test_box_kernel!`]): the group's box first (in scalars), then its
/// eight chunks as two lanes of four.
macro_rules! cone_chunks_kernel {
    ($lane:ty, $splat:path, $load:path, $cone:expr, $b:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul, Sub};
        let (cone, b): (&Cone, &ChunkBoxes) = ($cone, $b);
        let o = cone.o;
        // Each rounding step of a plane's value is monotonic in each
        // coordinate: where the group's extreme corner is outside by more
        // than the allowance, every chunk's is.
        let group_outside = cone.n.iter().any(|n| {
            let c = |a: usize| {
                if n[a] >= 0.0 {
                    b.group_hi[a]
                } else {
                    b.group_lo[a]
                }
            };
            let v = (n[0] * (c(0) - o[0]) + n[1] * (c(1) - o[1])) + n[2] * (c(2) - o[2]);
            v < -cone.slack
        });
        if group_outside {
            u32::MAX
        } else {
            let s = $splat(-cone.slack);
            let (ox, oy, oz): ($lane, $lane, $lane) = ($splat(o[0]), $splat(o[1]), $splat(o[2]));
            let mut out = 0u32;
            for n in &cone.n {
                let pick = |a: usize| if n[a] >= 0.0 { &b.hi[a] } else { &b.lo[a] };
                let (cx, cy, cz) = (pick(0), pick(1), pick(2));
                let (nx, ny, nz): ($lane, $lane, $lane) =
                    ($splat(n[0]), $splat(n[1]), $splat(n[2]));
                for h in 0..2 {
                    let quad = |c: &[f64; 8]| -> [f64; 4] {
                        [c[4 * h], c[4 * h + 1], c[4 * h + 2], c[4 * h + 3]]
                    };
                    let v = nx
                        .mul($load(&quad(cx)).sub(ox))
                        .add(ny.mul($load(&quad(cy)).sub(oy)))
                        .add(nz.mul($load(&quad(cz)).sub(oz)));
                    // Not ≥ −allowance (NaN and −∞ of empty chunks included).
                    out |= (v.cmp_ge(s).move_mask() ^ 0xf) << (4 * h);
                }
            }
            nibbles(out)
        }
    }};
}

/// [`Cone::decide`]'s kernel over `$lane` lanes (as [`test_box_kernel!`]).
macro_rules! cone_decide_kernel {
    ($lane:ty, $splat:path, $load:path, $cone:expr, $g:expr, $skip:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, BitAnd, BitOr, Mul, Sub};
        let (cone, g, skip): (&Cone, &GroupSoa, u32) = ($cone, $g, $skip);
        let (s, ns): ($lane, $lane) = ($splat(cone.slack), $splat(-cone.slack));
        let o = cone.o;
        let (ox, oy, oz): ($lane, $lane, $lane) = ($splat(o[0]), $splat(o[1]), $splat(o[2]));
        let n: [($lane, $lane, $lane); 3] =
            cone.n.map(|n| ($splat(n[0]), $splat(n[1]), $splat(n[2])));
        let (mut sure, mut unsure) = (0u32, 0u32);
        for c in 0..g.len.div_ceil(4) {
            if (skip >> (4 * c)) & 0xf == 0xf {
                continue;
            }
            let quad = |a: &[f64; 32]| -> [f64; 4] {
                [a[4 * c], a[4 * c + 1], a[4 * c + 2], a[4 * c + 3]]
            };
            let dx = $load(&quad(&g.x)).sub(ox);
            let dy = $load(&quad(&g.y)).sub(oy);
            let dz = $load(&quad(&g.z)).sub(oz);
            let v0 = n[0].0.mul(dx).add(n[0].1.mul(dy)).add(n[0].2.mul(dz));
            let v1 = n[1].0.mul(dx).add(n[1].1.mul(dy)).add(n[1].2.mul(dz));
            let v2 = n[2].0.mul(dx).add(n[2].1.mul(dy)).add(n[2].2.mul(dz));
            let inside = v0
                .cmp_gt(s)
                .bitand(v1.cmp_gt(s))
                .bitand(v2.cmp_gt(s))
                .move_mask();
            let outside = v0
                .cmp_lt(ns)
                .bitor(v1.cmp_lt(ns))
                .bitor(v2.cmp_lt(ns))
                .move_mask();
            sure |= inside << (4 * c);
            unsure |= (!(inside | outside) & 0xf) << (4 * c);
        }
        (sure & !skip, unsure & !skip)
    }};
}

/// The cone from a receiver through a triangle (§4 of
/// `docs/algorithms/penumbra-casting.md`, "cone prefilter"): the three
/// planes through the receiver `o` and an edge, oriented inwards, in
/// unnormalised form `s·((t_a − o) × (t_b − o))·(y − o)`. In exact
/// arithmetic this is the value of the kernel's edge plane of sample `y`
/// at `o` (a triple product is translation invariant), so where the
/// prefilter is valid ([`Cone::new`]) a chunk of samples whose box is
/// outside one plane by more than the rounding allowance holds no sample
/// the kernel can mark: skipping it changes no bit.
#[derive(Debug, Clone, Copy)]
pub struct Cone {
    n: [[f64; 3]; 3],
    o: [f64; 3],
    slack: f64,
    s: f64,
}

impl Cone {
    /// The cone of receiver `o` and triangle `t`, or `None` where the
    /// prefilter's proof does not hold: the caller has checked that the
    /// light's box is strictly on one side of the triangle's plane by
    /// more than `slack` ([`light_clear_of_plane`]); here `o` must be off
    /// that plane by more than `slack` too (so `o` and a sample the kernel
    /// marks are on opposite sides, and the kernel's orientation is the
    /// exact one). `slack` comes from [`cone_slack`].
    #[inline]
    pub fn new(t: &[DVec3; 3], o: [f64; 3], slack: f64) -> Option<Cone> {
        let od = DVec3::from_array(o);
        let (a, b, c) = (t[0] - od, t[1] - od, t[2] - od);
        let n01 = a.cross(b);
        let n12 = b.cross(c);
        let n20 = c.cross(a);
        let det = a.dot(n12);
        if !(det.abs() > slack) {
            return None;
        }
        let s = if det > 0.0 { 1.0 } else { -1.0 };
        Some(Cone {
            n: [
                (n01 * s).to_array(),
                (n12 * s).to_array(),
                (n20 * s).to_array(),
            ],
            o,
            slack,
            s,
        })
    }

    /// The skip bits (four per chunk) of the chunks of `b` that are
    /// outside one of the cone's planes by more than the allowance:
    /// [`Cone::outside_chunks_scalar`]'s answer, bit for bit. First the
    /// group's box: each rounding step of a plane's value is monotonic in
    /// each coordinate, so where the group's extreme corner is outside by
    /// more than the allowance every chunk's is (all skipped). Then eight
    /// chunks as two lanes of four through the SIMD facade, each value
    /// computed as the scalar twin does.
    #[inline]
    pub fn outside_chunks(&self, b: &ChunkBoxes) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx::available() {
            // SAFETY: `available` checked that the CPU has AVX, the one
            // requirement of `outside_chunks_avx`.
            return unsafe { self.outside_chunks_avx(b) };
        }
        self.outside_chunks_lanes(b)
    }

    /// [`Cone::outside_chunks`] on the facade's lanes.
    #[inline]
    pub fn outside_chunks_lanes(&self, b: &ChunkBoxes) -> u32 {
        let load = |a: &[f64; 4]| f64x4::new(*a);
        cone_chunks_kernel!(f64x4, f64x4::splat, load, self, b)
    }

    /// [`Cone::outside_chunks`] in AVX registers: the same values, the
    /// same bits.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub fn outside_chunks_avx(&self, b: &ChunkBoxes) -> u32 {
        use crate::simd::avx::F64x4;
        cone_chunks_kernel!(F64x4, F64x4::splat, F64x4::load, self, b)
    }

    /// Whether every point of the ball of radius `radius` about the
    /// light's centre (the coordinates' origin) is outside one of the
    /// cone's planes by more than the allowance, as
    /// [`Cone::outside_chunks`] asks of a chunk's box: the value at the
    /// centre plus the normal's length times `radius`, each widened by
    /// `1e-9` relative (their rounding is ~1e-16). Then the kernel marks
    /// none of the light's samples — where the light is clear of the
    /// triangle's plane (for samples within the allowance of a splitting
    /// plane the kernel's orientation is not known, and they go to the
    /// kernel whatever the cone says).
    #[inline]
    pub fn misses_ball(&self, radius: f64) -> bool {
        let o = DVec3::from_array(self.o);
        self.n.iter().any(|n| {
            let n = DVec3::from_array(*n);
            let len = n.length();
            let reach = len * radius * (1.0 + 1e-9) + 1e-9 * len * o.length();
            -n.dot(o) + reach < -self.slack
        })
    }

    /// [`Cone::outside_chunks`], chunk by chunk (its scalar twin).
    #[inline]
    pub fn outside_chunks_scalar(&self, b: &ChunkBoxes) -> u32 {
        let mut out = 0u32;
        for n in &self.n {
            let pick = |a: usize| if n[a] >= 0.0 { &b.hi[a] } else { &b.lo[a] };
            let (cx, cy, cz) = (pick(0), pick(1), pick(2));
            for c in 0..8 {
                let v = (n[0] * (cx[c] - self.o[0]) + n[1] * (cy[c] - self.o[1]))
                    + n[2] * (cz[c] - self.o[2]);
                // Empty chunks give NaN or −∞: skipped either way.
                if !(v >= -self.slack) {
                    out |= 0xf << (4 * c);
                }
            }
        }
        out
    }
}

impl Cone {
    /// The orientation `s` (the sign of `det(t0 − o, t1 − o, t2 − o)`):
    /// where it differs from the light's side of the triangle's plane
    /// ([`light_side_of_plane`]), the receiver is on the light's side
    /// and the kernel marks no sample (its fourth plane, the triangle's,
    /// rejects the receiver for every sample).
    #[inline(always)]
    pub fn orientation(&self) -> f64 {
        self.s
    }

    /// The cone's verdict on the samples of `g` not set in `skip`:
    /// `(sure, unsure)`. A sample whose three cone values all exceed the
    /// allowance is marked by the kernel (`sure`); one with a value below
    /// minus the allowance is not (in neither set); the rest (`unsure`,
    /// a value within the allowance of 0: a tie up to rounding) must be
    /// asked of the kernel. Valid where [`Cone::new`]'s conditions hold
    /// and the receiver is on the far side of the triangle from the light
    /// ([`Cone::orientation`] equals the light's side). Four samples at a
    /// time through the SIMD facade, each value computed as
    /// [`Cone::decide_scalar`] does (same bits).
    #[inline]
    pub fn decide(&self, g: &GroupSoa, skip: u32) -> (u32, u32) {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx::available() {
            // SAFETY: `available` checked that the CPU has AVX, the one
            // requirement of `decide_avx`.
            return unsafe { self.decide_avx(g, skip) };
        }
        self.decide_lanes(g, skip)
    }

    /// [`Cone::decide`] on the facade's lanes.
    #[inline]
    pub fn decide_lanes(&self, g: &GroupSoa, skip: u32) -> (u32, u32) {
        let load = |a: &[f64; 4]| f64x4::new(*a);
        cone_decide_kernel!(f64x4, f64x4::splat, load, self, g, skip)
    }

    /// [`Cone::decide`] in AVX registers: the same values, the same bits.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where the CPU has AVX
    /// (`simd::avx::available`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub fn decide_avx(&self, g: &GroupSoa, skip: u32) -> (u32, u32) {
        use crate::simd::avx::F64x4;
        cone_decide_kernel!(F64x4, F64x4::splat, F64x4::load, self, g, skip)
    }

    /// [`Cone::decide`], sample by sample (its scalar twin).
    #[inline]
    pub fn decide_scalar(&self, g: &GroupSoa, skip: u32) -> (u32, u32) {
        let o = self.o;
        let (mut sure, mut unsure) = (0u32, 0u32);
        for j in 0..g.len {
            if (skip >> j) & 1 == 1 {
                continue;
            }
            let d = [g.x[j] - o[0], g.y[j] - o[1], g.z[j] - o[2]];
            let v = self.n.map(|n| (n[0] * d[0] + n[1] * d[1]) + n[2] * d[2]);
            if v.iter().all(|&v| v > self.slack) {
                sure |= 1 << j;
            } else if !v.iter().any(|&v| v < -self.slack) {
                unsure |= 1 << j;
            }
        }
        (sure, unsure)
    }
}

/// The sides of triangle `t`'s plane the samples of `g` are on, clear of
/// `slack` in the unnormalised value `((t1 − t0) × (t2 − t0))·(y − t0)`
/// ([`light_side_of_plane`]'s form): `(positive, negative)` bits. For a
/// sample in either set the kernel's orientation and its triangle-plane
/// side are the exact ones (the kernel computes the same value within
/// `400 ε M³`, far below the cone's allowance).
///
/// The group's box (`b`, its samples' chunk boxes) answers first: each
/// rounding step of the value is monotonic in each coordinate, so where
/// the box's least corner (for the normal) is clear on the positive side,
/// or its greatest on the negative one, every sample's value is too.
pub fn plane_sides(g: &GroupSoa, b: &ChunkBoxes, t: &[DVec3; 3], slack: f64) -> (u32, u32) {
    let nt = cross(t[1] - t[0], t[2] - t[0]);
    let all = if g.len >= 32 {
        u32::MAX
    } else {
        (1u32 << g.len) - 1
    };
    let corner = |least: bool| {
        let c = |a: usize| {
            if (nt[a] >= 0.0) == least {
                b.group_lo[a]
            } else {
                b.group_hi[a]
            }
        };
        DVec3::new(c(0), c(1), c(2))
    };
    if nt.dot(corner(true) - t[0]) > slack {
        return (all, 0);
    }
    if nt.dot(corner(false) - t[0]) < -slack {
        return (0, all);
    }
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx::available() {
        // SAFETY: `available` checked that the CPU has AVX, the one
        // requirement of `plane_sides_avx`.
        return unsafe { plane_sides_avx(g, nt, t[0], slack) };
    }
    plane_sides_lanes(g, nt, t[0], slack)
}

/// [`plane_sides`]' per-sample values over `$lane` lanes (as
/// [`test_box_kernel!`]), each computed as [`plane_sides_scalar`] does:
/// `((nx (x − t0x) + ny (y − t0y)) + nz (z − t0z))`.
macro_rules! plane_sides_kernel {
    ($lane:ty, $splat:path, $load:path, $g:expr, $nt:expr, $t0:expr, $slack:expr) => {{
        #[allow(unused_imports)]
        use std::ops::{Add, Mul, Sub};
        let (g, nt, t0, slack): (&GroupSoa, DVec3, DVec3, f64) = ($g, $nt, $t0, $slack);
        let (s, ns): ($lane, $lane) = ($splat(slack), $splat(-slack));
        let (nx, ny, nz): ($lane, $lane, $lane) = ($splat(nt.x), $splat(nt.y), $splat(nt.z));
        let (ox, oy, oz): ($lane, $lane, $lane) = ($splat(t0.x), $splat(t0.y), $splat(t0.z));
        let (mut pos, mut neg) = (0u32, 0u32);
        for c in 0..g.len.div_ceil(4) {
            let quad = |a: &[f64; 32]| -> [f64; 4] {
                [a[4 * c], a[4 * c + 1], a[4 * c + 2], a[4 * c + 3]]
            };
            let v = nx
                .mul($load(&quad(&g.x)).sub(ox))
                .add(ny.mul($load(&quad(&g.y)).sub(oy)))
                .add(nz.mul($load(&quad(&g.z)).sub(oz)));
            pos |= v.cmp_gt(s).move_mask() << (4 * c);
            neg |= v.cmp_lt(ns).move_mask() << (4 * c);
        }
        // The padding lanes beyond the group's samples hold nothing.
        let all = if g.len >= 32 {
            u32::MAX
        } else {
            (1u32 << g.len) - 1
        };
        (pos & all, neg & all)
    }};
}

/// [`plane_sides`]' per-sample part on the facade's lanes (normal `nt`,
/// vertex `t0`).
pub fn plane_sides_lanes(g: &GroupSoa, nt: DVec3, t0: DVec3, slack: f64) -> (u32, u32) {
    let load = |a: &[f64; 4]| f64x4::new(*a);
    plane_sides_kernel!(f64x4, f64x4::splat, load, g, nt, t0, slack)
}

/// [`plane_sides_lanes`] in AVX registers: the same values, the same bits.
///
/// # Safety
///
/// Outside AVX code, call only where the CPU has AVX
/// (`simd::avx::available`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
pub fn plane_sides_avx(g: &GroupSoa, nt: DVec3, t0: DVec3, slack: f64) -> (u32, u32) {
    use crate::simd::avx::F64x4;
    plane_sides_kernel!(F64x4, F64x4::splat, F64x4::load, g, nt, t0, slack)
}

/// [`plane_sides`]' per-sample part, sample by sample (its scalar twin).
pub fn plane_sides_scalar(g: &GroupSoa, nt: DVec3, t0: DVec3, slack: f64) -> (u32, u32) {
    let (mut pos, mut neg) = (0u32, 0u32);
    for j in 0..g.len {
        let v = nt.dot(DVec3::new(g.x[j], g.y[j], g.z[j]) - t0);
        if v > slack {
            pos |= 1 << j;
        } else if v < -slack {
            neg |= 1 << j;
        }
    }
    (pos, neg)
}

/// The cone's verdict on one group (`boxes` and `soa` its samples),
/// testing the samples not set in `skip`: `(sure, unsure)` as
/// [`Cone::decide`] (`unsure` for the kernel). `sides`: `None` where the
/// light is clear of the triangle's plane on the receiver's far side
/// (the caller has checked [`Cone::orientation`]); else the samples'
/// sides ([`plane_sides`]) of a plane that splits the light: samples on
/// the receiver's side are not marked (the kernel's triangle plane
/// rejects the receiver), those on the far side are decided by the cone
/// as for a clear light, and those within the allowance of the plane
/// (whose kernel orientation is not known in advance) are `unsure`.
/// `simd`: [`Cone::decide`] or its scalar twin (same bits).
#[inline(always)]
pub fn cone_group(
    c: &Cone,
    soa: &GroupSoa,
    boxes: &ChunkBoxes,
    skip: u32,
    sides: Option<(u32, u32)>,
    simd: bool,
) -> (u32, u32) {
    let (mut skip, near) = match sides {
        None => (skip, 0),
        Some((pos, neg)) => {
            let far = if c.orientation() > 0.0 { pos } else { neg };
            let near = !(pos | neg);
            (skip | !(far | near), near & !skip)
        }
    };
    if skip | near == u32::MAX {
        return (0, near);
    }
    // The cone's chunk test holds for the samples clear of the plane.
    skip |= c.outside_chunks(boxes) & !near;
    let skip = skip | near;
    if skip == u32::MAX {
        return (0, near);
    }
    let (sure, unsure) = if simd {
        c.decide(soa, skip)
    } else {
        c.decide_scalar(soa, skip)
    };
    (sure, unsure | near)
}

/// Bit `c` of `m` (c < 8) spread to the nibble `4c .. 4c + 4`.
#[inline(always)]
pub fn nibbles(m: u32) -> u32 {
    let x = m & 0xff;
    let x = (x | x << 12) & 0x000f_000f;
    let x = (x | x << 6) & 0x0303_0303;
    let x = (x | x << 3) & 0x1111_1111;
    x * 0xf
}

/// Bit `c` (c < 8) set where nibble `c` of `skip` is not all ones: the
/// chunks of four with a sample left to test.
#[inline(always)]
pub fn chunks_left(skip: u32) -> u8 {
    let x = !skip;
    let x = (x | x >> 1 | x >> 2 | x >> 3) & 0x1111_1111;
    let x = (x | x >> 3) & 0x0303_0303;
    let x = (x | x >> 6) & 0x000f_000f;
    ((x | x >> 12) & 0xff) as u8
}

/// The cone prefilter's allowance for coordinates (relative to the
/// light's centre) of magnitude at most `m`: `CONE_C · m³`, rounded up.
pub fn cone_slack(m: f64) -> f64 {
    CONE_C * m * m * m * (1.0 + 1e-6)
}

/// Whether every corner of `light` is strictly on one side of the plane
/// of `t`, by more than `slack` in the unnormalised value
/// `((t1 − t0) × (t2 − t0))·(c − t0)`: then every sample is, so the
/// kernel's per-sample orientation (the sign of that value) is exact.
pub fn light_clear_of_plane(light: &LightBox, t: &[DVec3; 3], slack: f64) -> bool {
    light_side_of_plane(light, t, slack).is_some()
}

/// [`light_clear_of_plane`], with the side: `Some(1.0)` where every
/// corner's value is `> slack`, `Some(-1.0)` where every one is
/// `< −slack`, else `None`.
pub fn light_side_of_plane(light: &LightBox, t: &[DVec3; 3], slack: f64) -> Option<f64> {
    let nt = cross(t[1] - t[0], t[2] - t[0]);
    let v = light.corners.map(|c| nt.dot(c - t[0]));
    if v.iter().all(|&x| x > slack) {
        Some(1.0)
    } else if v.iter().all(|&x| x < -slack) {
        Some(-1.0)
    } else {
        None
    }
}

/// [`light_side_of_plane`] for a light whose samples all lie in the ball
/// of radius `radius` about its centre (the origin of the coordinates):
/// a sphere light, whose box reaches √3 times as far along its diagonals.
/// The value at a sample `y` is the value at the centre plus
/// `((t1 − t0) × (t2 − t0))·y`, at most the normal's length times
/// `radius` in magnitude; both computed terms are widened by `1e-9`
/// relative (their rounding is ~1e-16), so where the result is clear of
/// `slack` every sample's exact value is too.
pub fn ball_side_of_plane(radius: f64, t: &[DVec3; 3], slack: f64) -> Option<f64> {
    let nt = cross(t[1] - t[0], t[2] - t[0]);
    let centre = -nt.dot(t[0]);
    let len = nt.length();
    let reach = len * radius * (1.0 + 1e-9) + 1e-9 * len * t[0].length();
    if centre - reach > slack {
        Some(1.0)
    } else if centre + reach < -slack {
        Some(-1.0)
    } else {
        None
    }
}

/// One group's sample positions as lanes (padded to 32 with zeros).
#[derive(Debug, Clone)]
pub struct GroupSoa {
    /// x per sample.
    pub x: [f64; 32],
    /// y per sample.
    pub y: [f64; 32],
    /// z per sample.
    pub z: [f64; 32],
    /// Samples in the group.
    pub len: usize,
}

impl GroupSoa {
    /// The lanes of `samples` (≤ 32).
    pub fn new(samples: &[DVec3]) -> GroupSoa {
        let mut g = GroupSoa {
            x: [0.0; 32],
            y: [0.0; 32],
            z: [0.0; 32],
            len: samples.len(),
        };
        for (j, p) in samples.iter().enumerate() {
            g.x[j] = p.x;
            g.y[j] = p.y;
            g.z[j] = p.z;
        }
        g
    }
}

/// The point-in-hard-volume kernel for one point against one group's 32
/// volumes, for a lane module (the SIMD facade or its scalar twin): the
/// bits of the samples whose volume holds `o`, testing only the samples
/// whose bit is clear in `skip`.
macro_rules! kernel {
    ($name:ident, $lanes:path) => {
        /// The bits of the samples of `v` whose hard shadow volume holds
        /// `o`, among those not set in `skip`.
        #[inline]
        pub fn $name(v: &HardVolumes, o: [f64; 3], skip: u32) -> u32 {
            use $lanes as l;
            let (px, py, pz) = (
                l::f64x4::splat(o[0]),
                l::f64x4::splat(o[1]),
                l::f64x4::splat(o[2]),
            );
            let zero = l::f64x4::ZERO;
            let mut out = 0u32;
            let chunks = v.len.div_ceil(4);
            for c in 0..chunks {
                if (skip >> (4 * c)) & 0xf == 0xf {
                    continue;
                }
                let r = 4 * c..4 * c + 4;
                let mut inside: Option<l::f64x4> = None;
                // The edges first (they reject most lanes), then the
                // triangle's plane; stop once no lane is left inside (the
                // bits, an AND, do not depend on the order).
                for q in [0, 1, 2, 3] {
                    let nx = l::f64x4::load(&v.nx[q][r.clone()]);
                    let ny = l::f64x4::load(&v.ny[q][r.clone()]);
                    let nz = l::f64x4::load(&v.nz[q][r.clone()]);
                    let d = l::f64x4::load(&v.d[q][r.clone()]);
                    let val = ((nx * px + ny * py) + nz * pz) + d;
                    let m = val.cmp_gt(zero);
                    let i = match inside {
                        None => m,
                        Some(i) => i & m,
                    };
                    inside = Some(i);
                    if !i.any() {
                        break;
                    }
                }
                let bits = inside.map_or(0, |m| m.move_mask());
                out |= bits << (4 * c);
            }
            out & !skip
        }
    };
}

kernel!(hard_bits_simd, crate::simd);
kernel!(hard_bits_scalar, crate::simd::scalar);

#[cfg(test)]
mod tests {
    use super::*;

    /// A small reproducible generator.
    fn rng(state: &mut u64) -> f64 {
        // One SplitMix64 step from the previous draw.
        *state = crate::sampling::SplitMix64::new(*state).next_u64();
        (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    #[test]
    fn nibble_helpers_equal_their_loops() {
        for m in 0..256u32 {
            let mut want = 0u32;
            for c in 0..8 {
                if (m >> c) & 1 == 1 {
                    want |= 0xf << (4 * c);
                }
            }
            assert_eq!(nibbles(m), want);
        }
        let mut st = 3u64;
        for i in 0..20_000u64 {
            st = crate::sampling::mix64(st.wrapping_add(i));
            // Nibbles mostly all ones or all zeros, some mixed.
            let skip = nibbles(st as u32) | (st >> 32) as u32 & (st >> 40) as u32;
            let mut want = 0u8;
            for c in 0..8 {
                if (skip >> (4 * c)) & 0xf != 0xf {
                    want |= 1 << c;
                }
            }
            assert_eq!(chunks_left(skip), want, "{skip:#x}");
        }
    }

    #[test]
    fn cone_simd_equals_its_scalar_twin() {
        let mut st = 11u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let (mut all, mut some) = (0usize, 0usize);
        for round in 0..400 {
            let len = 1 + round % 32;
            let samples: Vec<DVec3> = (0..len)
                .map(|_| v(&mut st) * 0.5 + DVec3::new(0.0, 2.0, 0.0))
                .collect();
            let boxes = ChunkBoxes::new(&samples);
            let t = [v(&mut st), v(&mut st), v(&mut st)];
            for _ in 0..30 {
                let o = (v(&mut st) * 3.0 - DVec3::new(0.0, 2.0, 0.0)).to_array();
                let Some(c) = Cone::new(&t, o, 1e-12) else {
                    continue;
                };
                let x = c.outside_chunks(&boxes);
                assert_eq!(x, c.outside_chunks_scalar(&boxes));
                // (`outside_chunks` runs the AVX copy where the CPU has AVX.)
                assert_eq!(c.outside_chunks_lanes(&boxes), x);
                all += usize::from(x == u32::MAX);
                some += usize::from(x != u32::MAX && x != 0 && len > 4);
            }
        }
        assert!(all > 1000 && some > 300, "{all} {some}");
    }

    /// A thin light box (half extents `e`, 1 % wider) centred at `c`.
    fn thin_light(c: DVec3, e: DVec3) -> LightBox {
        let corners = std::array::from_fn(|i| {
            let f = |b: usize| if i & b != 0 { 1.0 } else { -1.0 };
            c + e * 1.01 * DVec3::new(f(1), f(2), f(4))
        });
        LightBox { corners }
    }

    /// The lanes of a group of `len ≤ 32` samples.
    fn lanes(len: usize) -> u32 {
        if len == 32 {
            u32::MAX
        } else {
            (1u32 << len) - 1
        }
    }

    /// Query `q`'s receiver: every third one random, the others on the
    /// line from a sample through a point of a triangle edge, beyond it
    /// (ties up to rounding), moved by `tiny` in a random direction.
    fn receiver(st: &mut u64, q: usize, samples: &[DVec3], t: &[DVec3; 3], tiny: f64) -> [f64; 3] {
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        if q.is_multiple_of(3) {
            return (v(st) * 2.0).to_array();
        }
        let y = samples[(*st as usize >> 3) % samples.len()];
        let a = (*st as usize >> 9) % 3;
        let mu = rng(st) + 0.5;
        let p = t[a] + (t[(a + 1) % 3] - t[a]) * mu;
        let lam = 1.2 + rng(st).abs() * 2.0;
        (y + (p - y) * lam + v(st) * tiny).to_array()
    }

    /// A sphere light's tests are conservative: where the ball is clear
    /// of a triangle's plane every sample on the sphere is clear on that
    /// side by the allowance ([`plane_sides`]), and where a cone misses
    /// the ball the kernel marks no sample; receivers placed on the lines
    /// from samples through the triangle's edges make near misses.
    #[test]
    fn sphere_ball_tests_are_conservative() {
        let mut st = 11u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let (mut clear, mut missed, mut hit) = (0usize, 0usize, 0usize);
        for round in 0..400 {
            let r = 0.1 + rng(&mut st).abs();
            // Samples on the sphere about the origin (the light's centre).
            let samples: Vec<DVec3> = (0..32)
                .map(|_| v(&mut st).normalize_or(DVec3::X) * r)
                .collect();
            let t = [v(&mut st), v(&mut st), v(&mut st)].map(|p| p * 2.0 - DVec3::Y * 2.0);
            let slack = cone_slack(4.0);
            let Some(side) = ball_side_of_plane(r, &t, slack) else {
                continue;
            };
            clear += 1;
            let soa = GroupSoa::new(&samples);
            let (pos, neg) = plane_sides(&soa, &ChunkBoxes::new(&samples), &t, slack);
            assert_eq!(
                if side > 0.0 { pos } else { neg },
                u32::MAX,
                "round {round}"
            );
            let mut hv = HardVolumes::default();
            hv.build(&soa, &t);
            for q in 0..60 {
                let o = receiver(&mut st, q, &samples, &t, 1e-15);
                let Some(cone) = Cone::new(&t, o, slack) else {
                    continue;
                };
                let k = hard_bits_scalar(&hv, o, 0);
                if cone.misses_ball(r) {
                    missed += 1;
                    assert_eq!(k, 0, "round {round}: a cone missing the ball marks");
                } else {
                    hit += usize::from(k != 0);
                }
            }
        }
        assert!(
            clear > 200 && missed > 1000 && hit > 1000,
            "{clear} {missed} {hit}"
        );
    }

    /// The cone's verdicts are the kernel's: every `sure` sample is
    /// marked, every marked sample is `sure` or `unsure`, and a receiver
    /// on the light's side gets nothing; with receivers placed on the
    /// lines from samples through the triangle's edges (ties up to
    /// rounding), so `unsure` samples occur.
    #[test]
    fn cone_decisions_are_the_kernels_bits() {
        let mut st = 5u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let (mut marked, mut unsure_seen, mut away, mut tested) = (0usize, 0usize, 0usize, 0usize);
        for round in 0..400 {
            let len = 1 + round % 32;
            // A thin light box at y = 2 and samples inside it.
            let e = DVec3::new(0.2 + 0.3 * rng(&mut st).abs(), 1e-9, 0.2);
            let c = DVec3::new(0.0, 2.0, 0.0);
            let samples: Vec<DVec3> = (0..len).map(|_| c + v(&mut st) * 2.0 * e).collect();
            let light = thin_light(c, e);
            let t = [v(&mut st), v(&mut st), v(&mut st)].map(|p| p + DVec3::new(0.0, 1.0, 0.0));
            let m = 4.0;
            let slack = cone_slack(m);
            let Some(side) = light_side_of_plane(&light, &t, slack) else {
                continue;
            };
            let soa = GroupSoa::new(&samples);
            let mut hv = HardVolumes::default();
            hv.build(&soa, &t);
            let valid = lanes(len);
            for q in 0..60 {
                let tiny = if q % 3 == 1 { 0.0 } else { 1e-15 };
                let o = receiver(&mut st, q, &samples, &t, tiny);
                if o.iter().any(|x| x.abs() > m) {
                    continue;
                }
                let Some(cone) = Cone::new(&t, o, slack) else {
                    continue;
                };
                let skip = !valid | ((round as u32).wrapping_mul(0x9e37_79b9) & 0x0101_0101);
                let k = hard_bits_simd(&hv, o, skip);
                tested += 1;
                if cone.orientation() != side {
                    assert_eq!(k, 0, "round {round}: a receiver on the light's side");
                    away += 1;
                    continue;
                }
                let (sure, unsure) = cone.decide(&soa, skip);
                assert_eq!((sure, unsure), cone.decide_scalar(&soa, skip));
                assert_eq!(cone.decide_lanes(&soa, skip), (sure, unsure));
                assert_eq!(sure & !k, 0, "round {round}: sure but not marked");
                assert_eq!(k & !(sure | unsure), 0, "round {round}: marked, not sure");
                assert_eq!((sure | unsure) & skip, 0);
                let fallback = hard_bits_scalar(&hv, o, !unsure);
                assert_eq!(sure | fallback, k);
                marked += k.count_ones() as usize;
                unsure_seen += unsure.count_ones() as usize;
            }
        }
        assert!(
            marked > 2000 && unsure_seen > 50 && away > 100 && tested > 5000,
            "{marked} {unsure_seen} {away} {tested}"
        );
    }

    /// [`cone_group`] with the kernel for its `unsure` samples gives the
    /// kernel's bits, for lights clear of the triangle's plane and for
    /// planes splitting the light (some samples placed on the plane
    /// itself, so the per-sample sides have ties), SIMD and scalar.
    #[test]
    fn cone_group_with_the_kernel_for_ties_is_the_kernel() {
        let mut st = 17u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let (mut marked, mut split_marked, mut near_seen, mut tested) = (0, 0, 0, 0);
        for round in 0..600 {
            let len = 1 + round % 32;
            let e = DVec3::new(0.3, 1e-9, 0.2);
            let c = DVec3::new(0.0, 2.0, 0.0);
            let light = thin_light(c, e);
            // Every other triangle leans so its plane crosses the light.
            let mut t = [v(&mut st), v(&mut st), v(&mut st)].map(|p| p + DVec3::new(0.0, 1.0, 0.0));
            if round % 2 == 1 {
                t[2] = c + DVec3::new(rng(&mut st) * 0.4, 0.0, 0.0);
            }
            let mut samples: Vec<DVec3> = (0..len).map(|_| c + v(&mut st) * 2.0 * e).collect();
            if round % 4 == 1 && len > 2 {
                // Samples on the plane (up to rounding): on its trace on
                // the light through the vertex there.
                let d = cross(t[1] - t[0], t[2] - t[0])
                    .cross(DVec3::Y)
                    .normalize_or_zero();
                for s in samples.iter_mut().take(len / 3) {
                    *s = t[2] + d * (rng(&mut st) * 0.1);
                }
            }
            let m = 4.0;
            let slack = cone_slack(m);
            let side = light_side_of_plane(&light, &t, slack);
            let soa = GroupSoa::new(&samples);
            let boxes = ChunkBoxes::new(&samples);
            let mut hv = HardVolumes::default();
            hv.build(&soa, &t);
            let valid = lanes(len);
            let sides = side.is_none().then(|| plane_sides(&soa, &boxes, &t, slack));
            // The group box's shortcut gives the per-sample sides.
            let nt = cross(t[1] - t[0], t[2] - t[0]);
            let (mut pos, mut neg) = (0u32, 0u32);
            for (j, y) in samples.iter().enumerate() {
                let v = nt.dot(*y - t[0]);
                pos |= u32::from(v > slack) << j;
                neg |= u32::from(v < -slack) << j;
            }
            assert_eq!(plane_sides(&soa, &boxes, &t, slack), (pos, neg));
            let t0 = t[0];
            assert_eq!(plane_sides_scalar(&soa, nt, t0, slack), (pos, neg));
            assert_eq!(plane_sides_lanes(&soa, nt, t0, slack), (pos, neg));
            #[cfg(target_arch = "x86_64")]
            if crate::simd::avx::available() {
                // SAFETY: the CPU has AVX (checked just above).
                assert_eq!(unsafe { plane_sides_avx(&soa, nt, t0, slack) }, (pos, neg));
            }
            for q in 0..60 {
                let o = receiver(&mut st, q, &samples, &t, 0.0);
                let Some(cone) = Cone::new(&t, o, slack) else {
                    continue;
                };
                let skip = !valid | ((round as u32).wrapping_mul(0x9e37_79b9) & 0x0101_0101);
                let k = hard_bits_simd(&hv, o, skip);
                if side.is_some_and(|s| s != cone.orientation()) {
                    assert_eq!(k, 0);
                    continue;
                }
                tested += 1;
                let (sure, unsure) = cone_group(&cone, &soa, &boxes, skip, sides, true);
                assert_eq!(
                    (sure, unsure),
                    cone_group(&cone, &soa, &boxes, skip, sides, false)
                );
                assert_eq!((sure | unsure) & skip, 0);
                assert_eq!(sure & unsure, 0);
                let got = sure | hard_bits_scalar(&hv, o, !unsure);
                assert_eq!(got, k, "round {round} q {q}: {sure:#x} {unsure:#x}");
                marked += k.count_ones();
                if sides.is_some() {
                    split_marked += k.count_ones();
                    near_seen += (unsure & !sides.map_or(0, |(p, n)| p | n)).count_ones();
                }
            }
        }
        assert!(
            marked > 3000 && split_marked > 1000 && near_seen > 10 && tested > 5000,
            "{marked} {split_marked} {near_seen} {tested}"
        );
    }

    #[test]
    fn simd_box_and_point_tests_equal_the_scalar_twins() {
        let mut st = 7u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let (mut outside, mut pruned, mut inside) = (0usize, 0usize, 0usize);
        for round in 0..300 {
            // A small light box above random triangles: volumes of 0 to
            // 32 planes (with random extra planes past the separating ones).
            let (c, e) = (DVec3::new(0.0, 2.0, 0.0), v(&mut st).abs() * 0.5);
            let mut corners = [DVec3::ZERO; 8];
            for (i, k) in corners.iter_mut().enumerate() {
                let f = |b: usize| if i & b != 0 { 1.0 } else { -1.0 };
                *k = c + e * DVec3::new(f(1), f(2), f(4));
            }
            let light = LightBox { corners };
            let t = [v(&mut st), v(&mut st), v(&mut st)];
            let mut vol = PenumbraVolume::default();
            penumbra_volume(&light, &t, &mut vol);
            while vol.planes.len() < round % 33 {
                let n = v(&mut st).normalize_or_zero();
                vol.planes.push(Plane {
                    n: n.to_array(),
                    d: rng(&mut st),
                });
            }
            vol.finish();
            assert!(vol.has_quads());
            // Half the points just behind the triangle as seen from the
            // light (mostly inside), half anywhere.
            let behind = (t[0] + t[1] + t[2]) / 3.0;
            let behind = behind + (behind - c) * 0.2;
            for k in 0..40 {
                let (a, b) = (v(&mut st) * 3.0, v(&mut st) * 3.0);
                let (lo, hi) = (a.min(b).to_array(), a.max(b).to_array());
                let active = ((st >> 7) as u32 | (st >> 41) as u32) & vol.all();
                for prune in [false, true] {
                    let x = vol.test_box(&lo, &hi, active, 1e-9, prune);
                    assert_eq!(x, vol.test_box_scalar(&lo, &hi, active, 1e-9, prune));
                    assert_eq!(vol.test_box_lanes(&lo, &hi, active, 1e-9, prune), x);
                    match x {
                        BoxTest::Outside => outside += 1,
                        BoxTest::Active(p) if p != active => pruned += 1,
                        _ => {}
                    }
                }
                let o = if k % 2 == 0 {
                    (v(&mut st) * 3.0).to_array()
                } else {
                    (behind + v(&mut st) * 0.05).to_array()
                };
                let x = vol.contains(o, active, 1e-9);
                assert_eq!(x, vol.contains_scalar(o, active, 1e-9));
                assert_eq!(vol.contains_lanes(o, active, 1e-9), x);
                inside += usize::from(x);
            }
        }
        // Every branch was taken often.
        assert!(
            outside > 500 && pruned > 500 && inside > 500,
            "{outside} {pruned} {inside}"
        );
    }

    #[test]
    fn simd_build_and_kernel_equal_the_scalar_twins() {
        let mut st = 1u64;
        let v = |s: &mut u64| DVec3::new(rng(s), rng(s), rng(s));
        let mut total = 0usize;
        for round in 0..200 {
            let len = 1 + round % 32;
            let samples: Vec<DVec3> = (0..len)
                .map(|_| v(&mut st) + DVec3::new(0.0, 2.0, 0.0))
                .collect();
            let t = [v(&mut st), v(&mut st), v(&mut st)];
            let (mut a, mut b) = (HardVolumes::default(), HardVolumes::default());
            a.build(&GroupSoa::new(&samples), &t);
            b.build_scalar(&samples, &t);
            let mut hits = 0usize;
            for _ in 0..50 {
                let o = (v(&mut st) * 4.0 - DVec3::new(0.0, 1.0, 0.0)).to_array();
                let skip = (round as u32).wrapping_mul(0x9e37_79b9) & 0x0f0f_0f0f;
                let x = hard_bits_simd(&a, o, skip);
                assert_eq!(x, hard_bits_scalar(&b, o, skip));
                assert_eq!(x, hard_bits_scalar(&a, o, skip));
                // The bits are the segment test, sample by sample.
                for (j, s) in samples.iter().enumerate() {
                    if (skip >> j) & 1 == 1 {
                        assert_eq!((x >> j) & 1, 0);
                        continue;
                    }
                    let frame = crate::geom::TriangleFrame::new(t);
                    let o = DVec3::from_array(o);
                    let hit = frame.hit(o, *s - o);
                    let crosses = hit.is_some_and(|(tt, b1, b2)| {
                        tt < 1.0 && b1 > 0.0 && b2 > 0.0 && b1 + b2 < 1.0
                    });
                    let ours = (x >> j) & 1 == 1;
                    if ours != crosses {
                        // Only within rounding of an edge or an end.
                        let near = hit.is_some_and(|(tt, b1, b2)| {
                            (tt - 1.0).abs() < 1e-9
                                || b1.abs().min(b2.abs()).min((1.0 - b1 - b2).abs()) < 1e-9
                        });
                        assert!(near, "round {round} sample {j}: {hit:?}");
                    }
                    hits += usize::from(ours);
                }
            }
            total += hits;
        }
        assert!(total > 500, "{total} blocked relations");
    }
}
