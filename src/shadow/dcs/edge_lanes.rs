//! A 4² pixel block's unbounded edges against its receivers, four
//! receivers per lane group: the counter pass's per-(receiver, edge) work
//! (`LightPass::group_edges`: the side of the edge's plane through the
//! centre, the multiplicity from the receiver, the projection onto a rect
//! light and its clipping) with the scalar code's IEEE operations in its
//! order per lane, so every receiver gets the bits its own pass would.
//!
//! The kernel is written once, in [`block_kernel!`], and compiled twice:
//! on the facade's [`f64x4`] ([`run_lanes`], what the build targets: two
//! SSE2 halves on plain x86-64) and, where the CPU has AVX, on
//! [`avx::F64x4`] inside an AVX function ([`run_avx`]), one 256-bit
//! register per operation. (A trait over the two lane types was tried:
//! its AVX methods, compiled without AVX, called every intrinsic out of
//! line, and the pass ran 1.9× slower.) The kernel uses only names both
//! types have: `add`, `sub`, `mul`, `div`, `bitand`, `bitor`, `not`,
//! `cmp_*`, `blend`, `move_mask`, `to_array`, `splat` and `new`.

use super::block_extras::{BlockExtras, BLOCK};
use super::counters::OrientedEdge;
use super::edges::{CandidateEdge, CandidateEdges};
use super::options::SilhouetteMode;
#[cfg(target_arch = "x86_64")]
use crate::simd::avx;
use crate::simd::f64x4;
use glam::DVec3;
#[allow(unused_imports)]
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Not, Sub};

/// One lane group's receivers (four, in lanes): shadow-ray origins `p'`,
/// raster points, and their rect-light projections' constants.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct GroupInputs {
    /// `p'` per axis.
    pub(super) p: [[f64; 4]; 3],
    /// The raster's receivers per axis.
    pub(super) raster: [[f64; 4]; 3],
    /// `RectProjection::parts`: `n`, `u_dual`, `v_dual` per axis.
    pub(super) n: [[f64; 4]; 3],
    pub(super) u_dual: [[f64; 4]; 3],
    pub(super) v_dual: [[f64; 4]; 3],
    pub(super) s_p: [f64; 4],
    pub(super) t_p: [f64; 4],
    /// Lanes with a projection (bit `k`); the others' ends are unread.
    pub(super) projected: u32,
    /// Lanes whose start count was already recounted (`Tie::Tied`).
    pub(super) tied: u32,
}

/// What the kernel reads besides the receivers.
pub(super) struct EdgeSource<'a> {
    pub(super) candidates: &'a CandidateEdges,
    /// Global id of the first candidate edge.
    pub(super) first_edge: u32,
    /// The light's centre.
    pub(super) centre: DVec3,
    pub(super) silhouettes: SilhouetteMode,
}

/// The kernel over `$lane` lanes, made by `$splat(v)` and `$new(array)`.
macro_rules! block_kernel {
    ($lane:ty, $splat:path, $new:path, $groups:ident, $edges:ident, $source:ident, $out:ident) => {{
        let load = |a: &[[f64; 4]; 3]| -> [$lane; 3] { [$new(a[0]), $new(a[1]), $new(a[2])] };
        let p: [[$lane; 3]; 4] = [
            load(&$groups[0].p),
            load(&$groups[1].p),
            load(&$groups[2].p),
            load(&$groups[3].p),
        ];
        let zero = $splat(0.0);
        for (id, mask) in $edges {
            let e: &CandidateEdge = &$source.candidates.edges[(id - $source.first_edge) as usize];
            for g in 0..4 {
                let live = u32::from(mask >> (4 * g)) & 0xF;
                if live == 0 {
                    continue;
                }
                let inputs = &$groups[g];
                // `side_of(q, v0, v1, centre)`: the sign of
                // `(v0 − q).cross(v1 − q).dot(centre − q)`, as glam
                // computes it.
                macro_rules! side_of {
                    ($q:expr) => {{
                        let q: &[$lane; 3] = $q;
                        let minus = |v: DVec3| -> [$lane; 3] {
                            [
                                $splat(v.x).sub(q[0]),
                                $splat(v.y).sub(q[1]),
                                $splat(v.z).sub(q[2]),
                            ]
                        };
                        let (a, b, c) = (minus(e.v0), minus(e.v1), minus($source.centre));
                        let x = a[1].mul(b[2]).sub(b[1].mul(a[2]));
                        let y = a[2].mul(b[0]).sub(b[2].mul(a[0]));
                        let z = a[0].mul(b[1]).sub(b[0].mul(a[1]));
                        let d = x.mul(c[0]).add(y.mul(c[1])).add(z.mul(c[2]));
                        let (pos, neg) = (d.cmp_gt(zero).move_mask(), d.cmp_lt(zero).move_mask());
                        [0, 1, 2, 3].map(|k| (pos >> k & 1) as i32 - (neg >> k & 1) as i32)
                    }};
                }
                let geometric = side_of!(&p[g]);
                let sided = (0..4).fold(0u32, |m, k| m | u32::from(geometric[k] != 0) << k) & live;
                for k in 0..4 {
                    $out.admitted[4 * g + k] += (live >> k & 1) as usize;
                }
                if e.quad_sign != 0 && sided & !inputs.tied != 0 {
                    let raster = load(&inputs.raster);
                    let at_raster = side_of!(&raster);
                    for k in 0..4 {
                        if (sided & !inputs.tied) >> k & 1 == 1 && at_raster[k] != geometric[k] {
                            $out.recount[4 * g + k] = true;
                        }
                    }
                }
                if sided & inputs.projected == 0 {
                    continue;
                }
                // `multiplicity_from`: per face, `normal · (p − point) > 0`.
                let mu = match $source.silhouettes {
                    SilhouetteMode::Centre if e.quad_sign != 0 => {
                        [e.quad_weight as i32 * i32::from(e.quad_sign); 4]
                    }
                    _ => {
                        let mut mu = [0; 4];
                        for f in $source.candidates.face_terms(e) {
                            let q = &p[g];
                            let dot = $splat(f.normal.x)
                                .mul(q[0].sub($splat(f.point.x)))
                                .add($splat(f.normal.y).mul(q[1].sub($splat(f.point.y))))
                                .add($splat(f.normal.z).mul(q[2].sub($splat(f.point.z))));
                            let front = dot.cmp_gt(zero).move_mask();
                            for (k, m) in mu.iter_mut().enumerate() {
                                *m += f.weights[(front >> k & 1) as usize];
                            }
                        }
                        mu
                    }
                };
                let wanted = (0..4).fold(0u32, |m, k| m | u32::from(mu[k] != 0) << k)
                    & sided
                    & inputs.projected;
                if wanted == 0 {
                    continue;
                }
                // `RectProjection::edge`: each end as `(S, T, W)` with
                // `d = q − p`, `W = d · n`, `S = u_dual · d + W s_p`, …
                let (n, u, v) = (load(&inputs.n), load(&inputs.u_dual), load(&inputs.v_dual));
                let (s_p, t_p) = ($new(inputs.s_p), $new(inputs.t_p));
                let project = |q: DVec3| -> [$lane; 3] {
                    let d = [
                        $splat(q.x).sub(p[g][0]),
                        $splat(q.y).sub(p[g][1]),
                        $splat(q.z).sub(p[g][2]),
                    ];
                    let dot =
                        |w: &[$lane; 3]| d[0].mul(w[0]).add(d[1].mul(w[1])).add(d[2].mul(w[2]));
                    let w = dot(&n);
                    [dot(&u).add(w.mul(s_p)), dot(&v).add(w.mul(t_p)), w]
                };
                let ([sa, ta, wa], [sb, tb, wb]) = (project(e.v0), project(e.v1));
                // `clip_to_square(a, b, 1)`: the early return of a
                // constraint both ends fail is a dead lane; `k0.max(r)`
                // (only where `fa < 0`, so `r ≥ 0`) a pick where `r > k0`,
                // `k1.min(r)` a pick where `r < k1` (equal values differ
                // at most in a zero's sign, and `k0 ≥ k1` then drops the
                // lane either way; a NaN `r` keeps the bound, as `max` and
                // `min` do).
                let one = $splat(1.0);
                let constraints = [
                    (wa, wb),
                    (one.sub(wa), one.sub(wb)),
                    (wa.sub(sa), wb.sub(sb)),
                    (wa.add(sa), wb.add(sb)),
                    (wa.sub(ta), wb.sub(tb)),
                    (wa.add(ta), wb.add(tb)),
                ];
                let (mut k0, mut k1, mut dead) = (zero, one, zero.cmp_gt(zero));
                for (fa, fb) in constraints {
                    let (na, nb) = (fa.cmp_lt(zero), fb.cmp_lt(zero));
                    if na.bitor(nb).move_mask() == 0 {
                        continue;
                    }
                    dead = dead.bitor(na.bitand(nb));
                    let r = fa.div(fa.sub(fb));
                    k0 = na.bitand(r.cmp_gt(k0)).blend(r, k0);
                    k1 = na.not().bitand(nb).bitand(r.cmp_lt(k1)).blend(r, k1);
                }
                let lerp = |k: $lane| {
                    [
                        sa.add(sb.sub(sa).mul(k)),
                        ta.add(tb.sub(ta).mul(k)),
                        wa.add(wb.sub(wa).mul(k)),
                    ]
                };
                let (from, to) = (k0.cmp_gt(zero), k1.cmp_lt(one));
                let (la, lb) = (lerp(k0), lerp(k1));
                let (sa, ta, wa) = (
                    from.blend(la[0], sa),
                    from.blend(la[1], ta),
                    from.blend(la[2], wa),
                );
                let (sb, tb, wb) = (
                    to.blend(lb[0], sb),
                    to.blend(lb[1], tb),
                    to.blend(lb[2], wb),
                );
                let dead = dead
                    .bitor(k0.cmp_ge(k1))
                    .bitor(wa.cmp_le(zero))
                    .bitor(wb.cmp_le(zero))
                    .move_mask();
                let wanted = wanted & !dead;
                if wanted == 0 {
                    continue;
                }
                let ends = [sa.div(wa), ta.div(wa), sb.div(wb), tb.div(wb)].map(|x| x.to_array());
                for k in 0..4 {
                    if wanted >> k & 1 == 0 {
                        continue;
                    }
                    let (a, b) = ([ends[0][k], ends[1][k]], [ends[2][k], ends[3][k]]);
                    if let Some(oriented) = OrientedEdge::new(a, b) {
                        $out.effective[4 * g + k].push((oriented, geometric[k] * mu[k]));
                    }
                }
            }
        }
    }};
}

/// The kernel on the facade's lanes. `edges`: each edge's global id and
/// the mask of the block's receivers it reached; `groups`: the block's
/// receivers, row by row; `out` gets each receiver's effective edges (in
/// `edges`' order), recount verdict and count of edges reached.
#[inline(always)]
pub(super) fn run_lanes(
    groups: &[GroupInputs; 4],
    edges: impl Iterator<Item = (u32, u16)>,
    source: &EdgeSource,
    out: &mut BlockExtras,
) {
    block_kernel!(f64x4, f64x4::splat, f64x4::new, groups, edges, source, out)
}

/// [`run_lanes`] in AVX registers.
///
/// # Safety
///
/// Outside AVX code, call only where the CPU has AVX
/// (`simd::avx::available`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
pub(super) fn run_avx(
    groups: &[GroupInputs; 4],
    edges: impl Iterator<Item = (u32, u16)>,
    source: &EdgeSource,
    out: &mut BlockExtras,
) {
    block_kernel!(
        avx::F64x4,
        avx::F64x4::splat,
        avx::F64x4::new,
        groups,
        edges,
        source,
        out
    )
}

/// Receivers of a block in lane groups: four rows of four.
pub(super) const GROUPS: usize = BLOCK / 4;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::EdgeAdjacency;
    use crate::shadow::dcs::edges::{side_of, LightShapeForSilhouettes};
    use crate::shadow::kit::light_frame::{RectFrame, RectProjection};

    /// Both kernels give every receiver what the scalar steps give it
    /// (`side_of`, `multiplicity_from`, `RectProjection::edge`,
    /// `OrientedEdge::new`), bit for bit and in order: the shipped bunny
    /// scene's candidate edges against receivers around them (some on the
    /// plane of an edge and the centre, some with no projection, some
    /// tied), in both silhouette modes.
    #[test]
    fn kernels_match_the_scalar_steps() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.toml");
        let scene = crate::scene::load_scene(&path).expect("shipped scene");
        let geometry = crate::geom::SceneGeometry::new(&scene);
        let adj = EdgeAdjacency::build(&geometry, |_| true);
        let frame = RectFrame::new(
            DVec3::new(0.1, 3.0, 0.2),
            DVec3::new(0.6, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.5),
        );
        let corners = frame.corners().map(|c| c.as_vec3());
        let lit = crate::geom::silhouette::faces_point(&adj, frame.center.as_vec3());
        let candidates = CandidateEdges::build(
            &adj,
            &lit,
            SilhouetteMode::WholeLight,
            LightShapeForSilhouettes::Polygon(&corners),
        );
        assert!(candidates.edges.len() > 100);
        let mut state = 7u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut pushed, mut recounts) = (0, 0);
        for round in 0..120 {
            let silhouettes = if round % 4 == 3 {
                SilhouetteMode::Centre
            } else {
                SilhouetteMode::WholeLight
            };
            let source = EdgeSource {
                candidates: &candidates,
                first_edge: 100,
                centre: frame.center,
                silhouettes,
            };
            let first = &candidates.edges[(round * 37) % candidates.edges.len()];
            let block = ReceiverBlock::random(round, first, &frame, &mut random);
            let groups = block.group_inputs();
            let edges: Vec<(u32, u16)> = (0..candidates.edges.len())
                .step_by(1 + round % 5)
                .map(|e| (100 + e as u32, (random() * 65536.0) as u16 | 0x0202))
                .collect();
            let mut lanes = BlockExtras::default();
            run_lanes(&groups, edges.iter().copied(), &source, &mut lanes);
            let want = block.scalar_steps(&edges, &source);
            assert_same_extras(&lanes, &want, &format!("round {round}"));
            #[cfg(target_arch = "x86_64")]
            if crate::simd::avx::available() {
                let mut wide = BlockExtras::default();
                // SAFETY: the CPU has AVX (checked).
                unsafe { run_avx(&groups, edges.iter().copied(), &source, &mut wide) };
                assert_same_extras(&wide, &want, &format!("round {round} (AVX)"));
            }
            pushed += want.effective.iter().map(Vec::len).sum::<usize>();
            recounts += want.recount.iter().filter(|&&b| b).count();
        }
        assert!(
            pushed > 10_000 && recounts > 10,
            "{pushed} edges, {recounts} recounts"
        );
    }

    /// One block of receivers of [`kernels_match_the_scalar_steps`].
    struct ReceiverBlock {
        /// Per receiver `(p', raster point)`.
        receivers: [(DVec3, DVec3); BLOCK],
        /// Their rect-light projections.
        projections: [Option<RectProjection>; BLOCK],
        /// Receivers whose raster point is tied.
        tied: [bool; BLOCK],
    }

    impl ReceiverBlock {
        /// Sixteen receivers: near the bunny, some on the plane of the
        /// `first` edge and the centre (raster point across it), one in
        /// the light's plane (no projection).
        fn random(
            round: usize,
            first: &CandidateEdge,
            frame: &RectFrame,
            random: &mut impl FnMut() -> f64,
        ) -> ReceiverBlock {
            let receivers: [(DVec3, DVec3); BLOCK] = std::array::from_fn(|k| {
                if k % 5 == 1 {
                    let on = first.v0 + (first.v1 - first.v0) * random();
                    let p = on + (on - frame.center) * random();
                    let off = DVec3::new(random(), random(), random()) * 1e-9;
                    (p + off, p - off)
                } else if k == 6 && round.is_multiple_of(3) {
                    let p = frame.center + frame.u * (2.0 * random());
                    (p, p)
                } else {
                    let p = DVec3::new(random() - 0.5, 0.6 * random(), random() - 0.5);
                    (p, p + DVec3::new(0.0, 1e-7, 0.0))
                }
            });
            ReceiverBlock {
                receivers,
                projections: receivers.map(|(p, _)| RectProjection::new(frame, p)),
                tied: std::array::from_fn(|k| (k + round).is_multiple_of(7)),
            }
        }

        /// The kernels' inputs: four receivers per group, a lane without a
        /// projection given its group's first one.
        fn group_inputs(&self) -> [GroupInputs; GROUPS] {
            let mut groups = [GroupInputs::default(); GROUPS];
            for (group, inputs) in groups.iter_mut().enumerate() {
                let row = &self.projections[4 * group..4 * group + 4];
                let any = row.iter().flatten().next().copied();
                for (lane, projection) in row.iter().enumerate() {
                    let k = 4 * group + lane;
                    for axis in 0..3 {
                        inputs.p[axis][lane] = self.receivers[k].0[axis];
                        inputs.raster[axis][lane] = self.receivers[k].1[axis];
                    }
                    inputs.tied |= u32::from(self.tied[k]) << lane;
                    inputs.projected |= u32::from(projection.is_some()) << lane;
                    if let Some(pr) = projection.or(any) {
                        let (_, n, u, v, s_p, t_p) = pr.parts();
                        for axis in 0..3 {
                            (
                                inputs.n[axis][lane],
                                inputs.u_dual[axis][lane],
                                inputs.v_dual[axis][lane],
                            ) = (n[axis], u[axis], v[axis]);
                        }
                        (inputs.s_p[lane], inputs.t_p[lane]) = (s_p, t_p);
                    }
                }
            }
            groups
        }

        /// The scalar steps, receiver by receiver, for `edges` (id and
        /// receiver mask).
        fn scalar_steps(&self, edges: &[(u32, u16)], source: &EdgeSource) -> BlockExtras {
            let (candidates, centre) = (source.candidates, source.centre);
            let mut want = BlockExtras::default();
            for &(id, mask) in edges {
                let e = &candidates.edges[id as usize - 100];
                for (k, &(p, raster)) in self.receivers.iter().enumerate() {
                    if mask >> k & 1 == 0 {
                        continue;
                    }
                    want.admitted[k] += 1;
                    let side = side_of(p, e.v0, e.v1, centre);
                    if e.quad_sign != 0
                        && !self.tied[k]
                        && side != 0
                        && side_of(raster, e.v0, e.v1, centre) != side
                    {
                        want.recount[k] = true;
                    }
                    let mu = match source.silhouettes {
                        SilhouetteMode::Centre if e.quad_sign != 0 => {
                            e.quad_weight as i32 * i32::from(e.quad_sign)
                        }
                        _ => candidates.multiplicity_from(e, p),
                    };
                    if side == 0 || mu == 0 {
                        continue;
                    }
                    let made = self.projections[k]
                        .and_then(|pr| pr.edge(e.v0, e.v1))
                        .and_then(|(a, b)| OrientedEdge::new(a, b));
                    if let Some(oriented) = made {
                        want.effective[k].push((oriented, side * mu));
                    }
                }
            }
            want
        }
    }

    /// Per receiver its effective edges as bits (end points) and
    /// multiplicities, in order.
    fn effective_bits(extras: &BlockExtras) -> Vec<Vec<([u32; 4], i32)>> {
        extras
            .effective
            .iter()
            .map(|list| {
                list.iter()
                    .map(|(oriented, multiplicity)| {
                        let (lo, hi) = (oriented.lo(), oriented.hi());
                        (
                            [lo[0], lo[1], hi[0], hi[1]].map(f32::to_bits),
                            *multiplicity,
                        )
                    })
                    .collect()
            })
            .collect()
    }

    /// A kernel's extras are the scalar steps' bit for bit.
    fn assert_same_extras(got: &BlockExtras, want: &BlockExtras, label: &str) {
        assert_eq!(effective_bits(got), effective_bits(want), "{label}");
        assert_eq!(got.recount, want.recount, "{label}");
        assert_eq!(got.admitted, want.admitted, "{label}");
    }
}
