//! Per-sample depth-complexity counters of one receiver, and the exact
//! per-sample test of which samples a projected edge covers.
//!
//! A sample `s` (chart coordinates, the light's centre at the origin) is
//! covered by the projected edge `lo → hi` — ordered so that
//! `cross(lo, hi) > 0` — when the segment from the origin to `s` crosses
//! it:
//!
//! ```text
//! cross(lo, s) ≥ 0  and  cross(hi, s) < 0  and  orient(lo, hi, s) < 0
//! ```
//!
//! (inside the sector from `lo` to `hi`, beyond the edge's line). The
//! sector is half-open: a sample exactly on the ray through a vertex
//! shared by two consecutive silhouette edges, where it is `hi` of one and
//! `lo` of the other, is counted by exactly one of them, because both
//! evaluate the same `cross(v, s)` on the same bits. Eight samples at a
//! time with `wide`; only exact IEEE operations (no fused multiply-add),
//! so every SIMD level gives the same counts. [`add_covered_scalar`] is
//! the same test one sample at a time, kept to test the SIMD one.
//!
//! Counters are `i32`: the depth complexity is bounded by the number of
//! caster faces, far below 2³¹ for any scene that fits in memory, so they
//! never wrap.

use crate::simd::{f32x8, i32x8};

/// Samples per SIMD step.
pub const LANES: usize = 8;

/// One receiver's samples in chart coordinates, structure-of-arrays,
/// padded to a multiple of [`LANES`] with the origin (never covered).
#[derive(Debug, Clone, Default)]
pub struct ChartSamples {
    xs: Vec<f32>,
    ys: Vec<f32>,
    n: usize,
}

impl ChartSamples {
    /// Replaces the samples.
    pub fn set(&mut self, points: impl Iterator<Item = [f64; 2]>) {
        self.clear();
        for p in points {
            self.push(p);
        }
        self.finish();
    }

    /// Starts a new set (then [`ChartSamples::push`] each sample and
    /// [`ChartSamples::finish`]).
    pub fn clear(&mut self) {
        self.xs.clear();
        self.ys.clear();
    }

    /// Appends a sample.
    #[inline]
    pub fn push(&mut self, [x, y]: [f64; 2]) {
        self.xs.push(x as f32);
        self.ys.push(y as f32);
    }

    /// Ends the set: pads it to a multiple of [`LANES`] with the origin.
    pub fn finish(&mut self) {
        self.n = self.xs.len();
        let padded = self.n.div_ceil(LANES) * LANES;
        self.xs.resize(padded, 0.0);
        self.ys.resize(padded, 0.0);
    }

    /// Number of (unpadded) samples.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Padded length (the counters' length).
    pub fn padded(&self) -> usize {
        self.xs.len()
    }

    /// Sample `k`'s chart coordinates as tested.
    pub fn get(&self, k: usize) -> [f32; 2] {
        [self.xs[k], self.ys[k]]
    }
}

/// An edge ready for the per-sample test: `cross(lo, hi) > 0`.
#[derive(Debug, Clone, Copy)]
pub struct OrientedEdge {
    lo: [f32; 2],
    hi: [f32; 2],
}

impl OrientedEdge {
    /// Orders the projected edge `a, b`; `None` when it is (in f32) in
    /// line with the centre, where it covers no sample.
    pub fn new(a: [f64; 2], b: [f64; 2]) -> Option<OrientedEdge> {
        let a = [a[0] as f32, a[1] as f32];
        let b = [b[0] as f32, b[1] as f32];
        // The orientation from the same f32 values the test uses.
        let o = f64::from(a[0]) * f64::from(b[1]) - f64::from(a[1]) * f64::from(b[0]);
        if o > 0.0 {
            Some(OrientedEdge { lo: a, hi: b })
        } else if o < 0.0 {
            Some(OrientedEdge { lo: b, hi: a })
        } else {
            None
        }
    }

    /// The end the covered sector starts from (`cross(lo, hi) > 0`), as
    /// the test uses it: other covered-sample tests (the bit-field tables
    /// of `bitfield`) must see the same f32 values.
    #[inline]
    pub fn lo(&self) -> [f32; 2] {
        self.lo
    }

    /// The end the covered sector stops at (excluded), as the test uses it.
    #[inline]
    pub fn hi(&self) -> [f32; 2] {
        self.hi
    }

    /// Whether the sample at chart point `s` is covered.
    #[inline]
    pub fn covers(&self, s: [f32; 2]) -> bool {
        let (lo, hi) = (self.lo, self.hi);
        let c_lo = lo[0] * s[1] - lo[1] * s[0];
        let c_hi = hi[0] * s[1] - hi[1] * s[0];
        let (dx, dy) = (hi[0] - lo[0], hi[1] - lo[1]);
        let beyond = dx * (s[1] - lo[1]) - dy * (s[0] - lo[0]);
        c_lo >= 0.0 && c_hi < 0.0 && beyond < 0.0
    }
}

/// Adds `delta` to the counter of every sample `edge` covers.
pub fn add_covered(counters: &mut [i32], samples: &ChartSamples, edge: &OrientedEdge, delta: i32) {
    let (lo, hi) = (edge.lo, edge.hi);
    let (lx, ly) = (f32x8::splat(lo[0]), f32x8::splat(lo[1]));
    let (hx, hy) = (f32x8::splat(hi[0]), f32x8::splat(hi[1]));
    let (dx, dy) = (f32x8::splat(hi[0] - lo[0]), f32x8::splat(hi[1] - lo[1]));
    let zero = f32x8::ZERO;
    let d = i32x8::splat(delta);
    for ((c, xs), ys) in counters
        .chunks_exact_mut(LANES)
        .zip(samples.xs.chunks_exact(LANES))
        .zip(samples.ys.chunks_exact(LANES))
    {
        let sx = f32x8::from(<[f32; LANES]>::try_from(xs).expect("chunks_exact(LANES)"));
        let sy = f32x8::from(<[f32; LANES]>::try_from(ys).expect("chunks_exact(LANES)"));
        let c_lo = lx * sy - ly * sx;
        let c_hi = hx * sy - hy * sx;
        let beyond = dx * (sy - ly) - dy * (sx - lx);
        let m = c_lo.cmp_ge(zero) & c_hi.cmp_lt(zero) & beyond.cmp_lt(zero);
        let m = m.cast_i32();
        let cur = i32x8::from(<[i32; LANES]>::try_from(&*c).expect("chunks_exact(LANES)"));
        let next = cur + (m & d);
        c.copy_from_slice(&next.to_array());
    }
}

/// [`add_covered`] one sample at a time (the scalar twin).
pub fn add_covered_scalar(
    counters: &mut [i32],
    samples: &ChartSamples,
    edge: &OrientedEdge,
    delta: i32,
) {
    for (k, c) in counters.iter_mut().enumerate().take(samples.padded()) {
        if edge.covers(samples.get(k)) {
            *c += delta;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(n: usize, seed: u64) -> ChartSamples {
        let mut s = ChartSamples::default();
        let mut x = seed;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let pts: Vec<[f64; 2]> = (0..n).map(|_| [next(), next()]).collect();
        s.set(pts.into_iter());
        s
    }

    #[test]
    fn simd_matches_scalar() {
        let s = samples(203, 5);
        for (a, b) in [
            ([-0.5, 0.3], [0.7, 0.4]),
            ([0.9, -0.9], [-0.9, -0.1]),
            ([0.1, 0.1], [0.1, 0.8]),
        ] {
            let e = OrientedEdge::new(a, b).unwrap();
            let mut v = vec![0; s.padded()];
            let mut w = vec![0; s.padded()];
            add_covered(&mut v, &s, &e, 3);
            add_covered_scalar(&mut w, &s, &e, 3);
            assert_eq!(v, w);
            assert!(v.contains(&3));
        }
    }

    #[test]
    fn consecutive_edges_share_the_ray_once() {
        // Samples exactly on the ray through the shared vertex v.
        let v = [0.25f64, 0.5];
        let mut s = ChartSamples::default();
        s.set((1..=16).map(|k| {
            let t = 1.0 + k as f64 * 0.1;
            [v[0] * t, v[1] * t]
        }));
        let e1 = OrientedEdge::new([0.5, -0.2], v).unwrap();
        let e2 = OrientedEdge::new(v, [-0.4, 0.3]).unwrap();
        let mut c = vec![0; s.padded()];
        add_covered(&mut c, &s, &e1, 1);
        add_covered(&mut c, &s, &e2, 1);
        // Beyond both edges near the vertex: each on-ray sample once.
        assert!(c[..s.len()].iter().all(|&k| k == 1), "{c:?}");
    }

    #[test]
    fn centre_in_line_covers_nothing() {
        assert!(OrientedEdge::new([0.2, 0.2], [0.4, 0.4]).is_none());
    }
}
