//! The per-receiver integral of penumbra wedges (thesis §3.1.3, algorithm
//! 3): the part of a rectangular light that one silhouette edge, seen from
//! a receiver point `p`, adds to or removes from the hard shadow cast from
//! the light's centre.
//!
//! Write `w(x)` for the number of shadow volumes `p` is in when the light
//! point is `x` (the stencil count the hard shadow volumes give for
//! `x = c`, the centre). Moving `x` from `c` along a straight line, `w`
//! changes by the edge's multiplicity `m` each time the segment crosses an
//! edge projected from `p` onto the light: `+m` when `p` is *outside* the
//! edge's shadow-volume quad (the outer half-wedge), `−m` inside (inner).
//! So the occluded fraction is
//!
//! ```text
//! V(p) = w(c) + Σ_e ±m_e · |R_e| / |A|
//! ```
//!
//! with `R_e` the part of the light beyond the projected edge as seen from
//! `c` (the cone from `c` through the edge, past the edge). With
//! non-overlapping silhouettes `V` is the occluded fraction exactly; the
//! technique's only approximation is the overlap (and silhouettes from the
//! centre only).
//!
//! Everything here is in f64 on the light's own parallelogram coordinates
//! `x = c + s·u + t·v`, `(s, t) ∈ [−1, 1]²`: area fractions survive the
//! affine map, so a parallelogram light is exact.

use glam::DVec3;

/// A rect light's frame: centre, half-edge vectors and their dual basis
/// (so that `s = u*·(x − c)` for points of the light's plane).
#[derive(Debug, Clone, Copy)]
pub struct RectFrame {
    /// Centre.
    pub center: DVec3,
    /// Half-edge vector `u`.
    pub u: DVec3,
    /// Half-edge vector `v`.
    pub v: DVec3,
    /// Unit normal `u × v / |u × v|`.
    pub normal: DVec3,
    u_dual: DVec3,
    v_dual: DVec3,
}

impl RectFrame {
    /// The frame of the parallelogram `c ± u ± v` (`u`, `v` not parallel).
    pub fn new(center: DVec3, u: DVec3, v: DVec3) -> Self {
        let normal = u.cross(v).normalize();
        let u_dual = v.cross(normal) / u.dot(v.cross(normal));
        let v_dual = normal.cross(u) / v.dot(normal.cross(u));
        RectFrame {
            center,
            u,
            v,
            normal,
            u_dual,
            v_dual,
        }
    }

    /// The light-plane coordinates `(s, t)` of `x` (`x = c + s u + t v`
    /// for points of the plane; the component along the normal is
    /// dropped).
    pub fn chart(&self, x: DVec3) -> [f64; 2] {
        let d = x - self.center;
        [self.u_dual.dot(d), self.v_dual.dot(d)]
    }

    /// The four corners, in order around the light.
    pub fn corners(&self) -> [DVec3; 4] {
        let (c, u, v) = (self.center, self.u, self.v);
        [c - u - v, c + u - v, c + u + v, c - u + v]
    }
}

/// A point of the projective light plane: `(s, t) = (S, T) / W`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Homogeneous {
    s: f64,
    t: f64,
    w: f64,
}

impl Homogeneous {
    fn lerp(self, o: Homogeneous, k: f64) -> Homogeneous {
        Homogeneous {
            s: self.s + (o.s - self.s) * k,
            t: self.t + (o.t - self.t) * k,
            w: self.w + (o.w - self.w) * k,
        }
    }
}

/// Fraction of the light (of area 4 in `(s, t)`) in `R_e` for the edge
/// `q0 → q1` seen from `p`, with `c_side` the side of the projected edge's
/// line the centre is on: `+1` when `(a, b, c)` turns counter-clockwise in
/// `(s, t)`, `−1` clockwise. The caller passes the side its rasterized
/// half-wedge membership implies, so that at ties (the centre exactly on
/// the projected edge, i.e. `p` on the shadow-volume quad) the region is
/// the limit from the side the stencil counted, and the total stays
/// continuous.
///
/// The edge is first clipped to the slab between `p`'s plane parallel to
/// the light (the local near plane: parts behind `p` cannot occlude it) and
/// the light's plane (parts beyond the light cannot either), then to the
/// light's square, all in homogeneous coordinates, so edges crossing `p`'s
/// plane (projections through infinity) need no special case.
pub fn region_fraction(frame: &RectFrame, p: DVec3, q0: DVec3, q1: DVec3, c_side: f64) -> f64 {
    match projected_edge(frame, p, q0, q1) {
        Some((a, b)) => {
            EdgeRegion::new(a, b, c_side)
                .polygon(Polygon::square())
                .area()
                / 4.0
        }
        None => 0.0,
    }
}

/// The edge `q0 → q1` seen from `p` on the light's square: clipped to the
/// slab between `p`'s plane and the light's (see [`region_fraction`]) and
/// to the square, as `(s, t)` endpoints; `None` when nothing is left.
pub fn projected_edge(
    frame: &RectFrame,
    p: DVec3,
    q0: DVec3,
    q1: DVec3,
) -> Option<([f64; 2], [f64; 2])> {
    RectProjection::new(frame, p)?.edge(q0, q1)
}

/// The projection from one receiver `p` onto a rect light's plane, its
/// per-receiver constants computed once for all the edges `p` sees.
#[derive(Debug, Clone, Copy)]
pub struct RectProjection {
    p: DVec3,
    /// The light's normal scaled so that `W = 1` on its plane.
    n: DVec3,
    u_dual: DVec3,
    v_dual: DVec3,
    s_p: f64,
    t_p: f64,
}

impl RectProjection {
    /// `None` when `p` is in the light's plane (it sees the light edge-on)
    /// or not finite.
    pub fn new(frame: &RectFrame, p: DVec3) -> Option<RectProjection> {
        let to_light = frame.center - p;
        let h_light = to_light.dot(frame.normal);
        if h_light == 0.0 || !h_light.is_finite() {
            return None;
        }
        // Coordinates so that W = 0 on p's plane and W = 1 on the light's.
        Some(RectProjection {
            p,
            n: frame.normal / h_light,
            u_dual: frame.u_dual,
            v_dual: frame.v_dual,
            s_p: frame.u_dual.dot(p - frame.center),
            t_p: frame.v_dual.dot(p - frame.center),
        })
    }

    /// Its constants `(p, n, u_dual, v_dual, s_p, t_p)`, for code that
    /// projects in lanes with [`RectProjection::edge`]'s operations.
    pub fn parts(&self) -> (DVec3, DVec3, DVec3, DVec3, f64, f64) {
        (self.p, self.n, self.u_dual, self.v_dual, self.s_p, self.t_p)
    }

    /// The edge `q0 → q1` projected and clipped (see [`projected_edge`]).
    #[inline]
    pub fn edge(&self, q0: DVec3, q1: DVec3) -> Option<([f64; 2], [f64; 2])> {
        let project = |q: DVec3| {
            let d = q - self.p;
            let w = d.dot(self.n);
            [
                self.u_dual.dot(d) + w * self.s_p,
                self.v_dual.dot(d) + w * self.t_p,
                w,
            ]
        };
        clip_to_square(project(q0), project(q1), 1.0)
    }
}

/// The segment between the homogeneous points `a` and `b` (`(S, T, W)`,
/// the point `(S/W, T/W)`) clipped to `0 ≤ W ≤ w_max` (in front of the
/// receiver, not beyond the light) and to the square `|S|, |T| ≤ W`, as
/// `(s, t)` endpoints; `None` when nothing is left. Unclipped ends are
/// returned bit-exact (see below).
#[inline(always)]
pub fn clip_to_square(a: [f64; 3], b: [f64; 3], w_max: f64) -> Option<([f64; 2], [f64; 2])> {
    let h = |v: [f64; 3]| Homogeneous {
        s: v[0],
        t: v[1],
        w: v[2],
    };
    let (a, b) = (h(a), h(b));
    // Liang–Barsky against f(P) ≥ 0 for each linear constraint.
    let constraints = [
        |h: &Homogeneous, _: f64| h.w,
        |h: &Homogeneous, m: f64| m - h.w,
        |h: &Homogeneous, _: f64| h.w - h.s,
        |h: &Homogeneous, _: f64| h.w + h.s,
        |h: &Homogeneous, _: f64| h.w - h.t,
        |h: &Homogeneous, _: f64| h.w + h.t,
    ];
    let (mut k0, mut k1) = (0.0f64, 1.0f64);
    for f in constraints {
        let (fa, fb) = (f(&a, w_max), f(&b, w_max));
        if fa < 0.0 && fb < 0.0 {
            return None;
        }
        if fa < 0.0 {
            k0 = k0.max(fa / (fa - fb));
        } else if fb < 0.0 {
            k1 = k1.min(fa / (fa - fb));
        }
    }
    if k0 >= k1 {
        return None;
    }
    // Unclipped ends stay bit-exact (`a + (b − a)·1` need not round to
    // `b`): two edges sharing a vertex then project it identically, which
    // depth complexity sampling's tie rule relies on.
    let (a, b) = (
        if k0 > 0.0 { a.lerp(b, k0) } else { a },
        if k1 < 1.0 { a.lerp(b, k1) } else { b },
    );
    // Inside the square, W ≥ |S|, |T|; W = 0 would be p itself (an edge
    // through the receiver: it occludes a set of measure zero).
    if a.w <= 0.0 || b.w <= 0.0 {
        return None;
    }
    Some(([a.s / a.w, a.t / a.w], [b.s / b.w, b.t / b.w]))
}

/// `R_e` for a projected edge `a → b` with the centre (the origin) on side
/// `c_side` of it: the part beyond the line `ab` from the centre, inside
/// the cone from the centre through the edge.
#[derive(Debug, Clone, Copy)]
pub struct EdgeRegion {
    a: [f64; 2],
    b: [f64; 2],
    sigma: f64,
}

fn orient(o: [f64; 2], d: [f64; 2], x: [f64; 2]) -> f64 {
    (d[0] - o[0]) * (x[1] - o[1]) - (d[1] - o[1]) * (x[0] - o[0])
}

impl EdgeRegion {
    /// The region of the projected edge `a → b`.
    pub fn new(a: [f64; 2], b: [f64; 2], c_side: f64) -> Self {
        EdgeRegion {
            a,
            b,
            sigma: if c_side < 0.0 { -1.0 } else { 1.0 },
        }
    }

    /// The three half-planes whose intersection is the region: beyond the
    /// line, and the two sides of the cone.
    /// As `(o, d, k)`: `k · orient(o, d, x) ≥ 0`.
    fn half_planes(&self) -> [([f64; 2], [f64; 2], f64); 3] {
        let s = self.sigma;
        [
            (self.a, self.b, -s),
            ([0.0, 0.0], self.a, s),
            ([0.0, 0.0], self.b, -s),
        ]
    }

    /// The region within the convex polygon `within`.
    pub fn polygon(&self, within: Polygon) -> Polygon {
        self.half_planes().iter().fold(within, |poly, &(o, d, k)| {
            poly.clip(|x| k * orient(o, d, x))
        })
    }

    /// Bounding box of `within` minus the region: the union of `within`
    /// cut by the complement of each of the three half-planes.
    pub fn complement_bbox(&self, within: Polygon) -> Option<[f64; 4]> {
        let pieces = self
            .half_planes()
            .map(|(o, d, k)| within.clip(|x| -k * orient(o, d, x)));
        pieces
            .iter()
            .filter(|p| p.area() > 0.0)
            .filter_map(Polygon::bbox)
            .reduce(|a, b| {
                [
                    a[0].min(b[0]),
                    a[1].min(b[1]),
                    a[2].max(b[2]),
                    a[3].max(b[3]),
                ]
            })
    }
}

/// Vertices a [`Polygon`] holds: a rectangle clipped by five half-planes
/// has at most 9.
const POLYGON_CAPACITY: usize = 10;

/// A convex polygon on the stack.
#[derive(Debug, Clone, Copy)]
pub struct Polygon {
    v: [[f64; 2]; POLYGON_CAPACITY],
    n: usize,
}

impl Polygon {
    /// The light's whole square `[−1, 1]²`.
    pub fn square() -> Self {
        Polygon::rect([-1.0, -1.0, 1.0, 1.0])
    }

    /// The rectangle `[x0, y0, x1, y1]`.
    pub fn rect([x0, y0, x1, y1]: [f64; 4]) -> Self {
        let mut v = [[0.0; 2]; POLYGON_CAPACITY];
        v[..4].copy_from_slice(&[[x0, y0], [x1, y0], [x1, y1], [x0, y1]]);
        Polygon { v, n: 4 }
    }

    /// Bounding box `[x0, y0, x1, y1]`, if not empty.
    pub fn bbox(&self) -> Option<[f64; 4]> {
        (self.n > 0).then(|| {
            self.v[..self.n].iter().fold(
                [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ],
                |b, p| {
                    [
                        b[0].min(p[0]),
                        b[1].min(p[1]),
                        b[2].max(p[0]),
                        b[3].max(p[1]),
                    ]
                },
            )
        })
    }

    /// Keeps the part where `f ≥ 0` (`f` affine).
    pub fn clip(&self, f: impl Fn([f64; 2]) -> f64) -> Polygon {
        let mut out = Polygon {
            v: [[0.0; 2]; POLYGON_CAPACITY],
            n: 0,
        };
        for i in 0..self.n {
            let a = self.v[i];
            let b = self.v[(i + 1) % self.n];
            let (fa, fb) = (f(a), f(b));
            if fa >= 0.0 && out.n < POLYGON_CAPACITY {
                out.v[out.n] = a;
                out.n += 1;
            }
            if (fa >= 0.0) != (fb >= 0.0) && out.n < POLYGON_CAPACITY {
                let k = fa / (fa - fb);
                out.v[out.n] = [a[0] + (b[0] - a[0]) * k, a[1] + (b[1] - a[1]) * k];
                out.n += 1;
            }
        }
        out
    }

    /// Absolute area.
    pub fn area(&self) -> f64 {
        let mut twice = 0.0;
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            twice += a[0] * b[1] - a[1] * b[0];
        }
        (twice * 0.5).abs()
    }
}

/// [`region_fraction`] for a sphere light: the fraction of the cone of
/// directions the sphere subtends from `p` (the contract's Vcoef measure:
/// solid angle) that lies beyond the edge as seen from the centre.
///
/// In gnomonic coordinates around the axis `p → c` (straight lines stay
/// straight), the cone is a disc of radius `tan θ` centred on the axis and
/// `R_e` is, per polar angle `φ` inside the edge's angular span, the radial
/// interval from the edge to the rim. With `dω = ρ dρ dφ / (1 + ρ²)^{3/2}`
/// its solid angle is `Δφ (1 − cos θ) − Ω(0, a, b)`, `Ω(0, a, b)` the solid
/// angle of the triangle from the axis to the edge (clipped to the disc),
/// by Van Oosterom & Strackee's formula. No side argument is needed: at a
/// tie both sides give half the cone.
///
/// The edge is first clipped to the slab between `p`'s plane normal to the
/// axis and the plane of the sphere's visible rim (parts beyond it are
/// inside the light).
pub fn region_fraction_sphere(center: DVec3, radius: f64, p: DVec3, q0: DVec3, q1: DVec3) -> f64 {
    let axis = center - p;
    let d = axis.length();
    if !(d > radius) || !d.is_finite() {
        return 0.0;
    }
    let a = axis / d;
    let e1 = a.any_orthonormal_vector();
    let e2 = a.cross(e1);
    let sin_t = radius / d;
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let tan_t = sin_t / cos_t;
    let rim = d * cos_t * cos_t;
    let project = |q: DVec3| {
        let v = q - p;
        Homogeneous {
            s: v.dot(e1),
            t: v.dot(e2),
            w: v.dot(a),
        }
    };
    let (mut h0, mut h1) = (project(q0), project(q1));
    // Keep W in [ε d, rim]: in front of p (a sliver at W → 0 projects
    // outside the disc anyway), not beyond the light.
    let eps = 1e-9 * d;
    for (f0, f1, keep_above, bound) in [(h0.w, h1.w, true, eps), (h0.w, h1.w, false, rim)] {
        let (g0, g1) = if keep_above {
            (f0 - bound, f1 - bound)
        } else {
            (bound - f0, bound - f1)
        };
        if g0 < 0.0 && g1 < 0.0 {
            return 0.0;
        }
        if g0 < 0.0 {
            h0 = h0.lerp(h1, g0 / (g0 - g1));
        } else if g1 < 0.0 {
            h1 = h1.lerp(h0, g1 / (g1 - g0));
        }
    }
    let a2 = [h0.s / h0.w, h0.t / h0.w];
    let b2 = [h1.s / h1.w, h1.t / h1.w];
    // Clip the segment to the disc |x| ≤ tan θ.
    let dx = [b2[0] - a2[0], b2[1] - a2[1]];
    let qa = dx[0] * dx[0] + dx[1] * dx[1];
    let qb = 2.0 * (a2[0] * dx[0] + a2[1] * dx[1]);
    let qc = a2[0] * a2[0] + a2[1] * a2[1] - tan_t * tan_t;
    let (k0, k1) = if qa == 0.0 {
        if qc > 0.0 {
            return 0.0;
        }
        (0.0, 1.0)
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc <= 0.0 {
            return 0.0;
        }
        let r = disc.sqrt();
        // Stable roots.
        let qq = -0.5 * (qb + qb.signum() * r);
        let (mut r0, mut r1) = (qq / qa, if qq != 0.0 { qc / qq } else { 0.0 });
        if r0 > r1 {
            std::mem::swap(&mut r0, &mut r1);
        }
        (r0.max(0.0), r1.min(1.0))
    };
    if k0 >= k1 {
        return 0.0;
    }
    let at = |k: f64| [a2[0] + dx[0] * k, a2[1] + dx[1] * k];
    let (pa, pb) = (at(k0), at(k1));
    let cross = pa[0] * pb[1] - pa[1] * pb[0];
    let dot = pa[0] * pb[0] + pa[1] * pb[1];
    let dphi = cross.abs().atan2(dot);
    // Van Oosterom & Strackee with r1 = axis, r2 = (pa, 1), r3 = (pb, 1).
    let (l2, l3) = (
        (1.0 + pa[0] * pa[0] + pa[1] * pa[1]).sqrt(),
        (1.0 + pb[0] * pb[0] + pb[1] * pb[1]).sqrt(),
    );
    let denom = l2 * l3 + l3 + l2 + (dot + 1.0);
    let tri = 2.0 * cross.abs().atan2(denom);
    let cone = std::f64::consts::TAU * (1.0 - cos_t);
    ((dphi * (1.0 - cos_t) - tri) / cone).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> RectFrame {
        // Light at y = 4 facing down, 1 × 1.
        RectFrame::new(
            DVec3::new(0.0, 4.0, 0.0),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.5),
        )
    }

    #[test]
    fn edge_straight_below_the_centre_splits_the_light_in_halves() {
        // Receiver at the origin, an edge halfway up through x = 0: from p
        // it projects onto the line s = 0 through the centre. Each side's
        // limit region is exactly half the light.
        let f = frame();
        let p = DVec3::ZERO;
        let (q0, q1) = (DVec3::new(0.0, 2.0, -5.0), DVec3::new(0.0, 2.0, 5.0));
        let plus = region_fraction(&f, p, q0, q1, 1.0);
        let minus = region_fraction(&f, p, q0, q1, -1.0);
        assert!((plus - 0.5).abs() < 1e-12, "{plus}");
        assert!((minus - 0.5).abs() < 1e-12, "{minus}");
    }

    #[test]
    fn region_is_the_part_beyond_the_edge_from_the_centre() {
        // Edge projecting to s = 0.5 (a quarter of the light beyond it).
        let f = frame();
        let p = DVec3::ZERO;
        // Halfway up, so s on the light is twice the edge's x / 0.5.
        let x = 0.5 * 0.5 * 0.5;
        let (q0, q1) = (DVec3::new(x, 2.0, -5.0), DVec3::new(x, 2.0, 5.0));
        let side = if region_fraction(&f, p, q0, q1, 1.0) > 0.0 {
            1.0
        } else {
            -1.0
        };
        let r = region_fraction(&f, p, q0, q1, side);
        assert!((r - 0.25).abs() < 1e-12, "{r}");
    }

    #[test]
    fn edges_behind_the_receiver_or_beyond_the_light_do_not_occlude() {
        let f = frame();
        let p = DVec3::ZERO;
        let below = region_fraction(
            &f,
            p,
            DVec3::new(0.1, -1.0, -5.0),
            DVec3::new(0.1, -1.0, 5.0),
            1.0,
        ) + region_fraction(
            &f,
            p,
            DVec3::new(0.1, -1.0, -5.0),
            DVec3::new(0.1, -1.0, 5.0),
            -1.0,
        );
        assert_eq!(below, 0.0);
        let above = region_fraction(
            &f,
            p,
            DVec3::new(0.1, 5.0, -5.0),
            DVec3::new(0.1, 5.0, 5.0),
            1.0,
        ) + region_fraction(
            &f,
            p,
            DVec3::new(0.1, 5.0, -5.0),
            DVec3::new(0.1, 5.0, 5.0),
            -1.0,
        );
        assert_eq!(above, 0.0);
    }

    #[test]
    fn an_edge_crossing_the_receivers_plane_is_clipped_not_inverted() {
        // From (0,2,-5) below-ish to a point under p's plane: the part above
        // p's plane projects to a ray leaving the light; a finite answer in
        // [0, 1] with no NaN.
        let f = frame();
        let p = DVec3::ZERO;
        for side in [1.0, -1.0] {
            let r = region_fraction(
                &f,
                p,
                DVec3::new(0.1, 1.0, 0.0),
                DVec3::new(0.1, -1.0, 3.0),
                side,
            );
            assert!(r.is_finite() && (0.0..=1.0).contains(&r), "{r}");
        }
        // Through p itself: measure zero.
        let r = region_fraction(
            &f,
            p,
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 1.0),
            1.0,
        );
        assert!(r.is_finite());
    }

    #[test]
    fn degenerate_edges_give_zero() {
        let f = frame();
        let q = DVec3::new(0.1, 2.0, 0.1);
        assert_eq!(region_fraction(&f, DVec3::ZERO, q, q, 1.0), 0.0);
        assert_eq!(region_fraction(&f, DVec3::ZERO, q, q, -1.0), 0.0);
        // Receiver in the light's plane.
        assert_eq!(
            region_fraction(&f, DVec3::new(3.0, 4.0, 0.0), q, q + DVec3::X, 1.0),
            0.0
        );
    }

    #[test]
    fn sphere_edge_through_the_axis_takes_half_the_cone_and_far_edges_nothing() {
        let (c, r) = (DVec3::new(0.0, 4.0, 0.0), 0.5);
        let p = DVec3::ZERO;
        let half = region_fraction_sphere(
            c,
            r,
            p,
            DVec3::new(0.0, 2.0, -5.0),
            DVec3::new(0.0, 2.0, 5.0),
        );
        assert!((half - 0.5).abs() < 1e-12, "{half}");
        let none = region_fraction_sphere(
            c,
            r,
            p,
            DVec3::new(3.0, 2.0, -5.0),
            DVec3::new(3.0, 2.0, 5.0),
        );
        assert_eq!(none, 0.0);
    }

    #[test]
    fn sphere_region_matches_a_solid_angle_quadrature() {
        // An edge off the axis, compared with a fine quadrature of the
        // solid-angle measure over the gnomonic disc.
        let (c, r) = (DVec3::new(0.0, 4.0, 0.0), 1.0);
        let p = DVec3::ZERO;
        let (q0, q1) = (DVec3::new(0.2, 2.0, -5.0), DVec3::new(0.05, 2.0, 5.0));
        let got = region_fraction_sphere(c, r, p, q0, q1);
        // Gnomonic plane at unit distance along +y: x = X/Y, z = Z/Y.
        let tan_t = (1.0f64 / 4.0) / (1.0f64 - 1.0 / 16.0).sqrt();
        let n = 2000;
        let (mut inside, mut total) = (0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                let x = -tan_t + (i as f64 + 0.5) * 2.0 * tan_t / n as f64;
                let z = -tan_t + (j as f64 + 0.5) * 2.0 * tan_t / n as f64;
                if x * x + z * z > tan_t * tan_t {
                    continue;
                }
                let w = 1.0 / (1.0 + x * x + z * z).powf(1.5);
                total += w;
                // Beyond the edge line from the centre (the centre is on
                // the side x < line): the edge at y = 2 projects to x = 2·X/4... at unit
                // distance: x = X / 2.
                let t = (z * 2.0 + 5.0) / 10.0; // edge parameter at this z
                let xe = (q0.x + (q1.x - q0.x) * t) / 2.0;
                if x > xe {
                    inside += w;
                }
            }
        }
        let want = inside / total;
        assert!((got - want).abs() < 2e-3, "{got} vs {want}");
    }
}
