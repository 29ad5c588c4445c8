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

use glam::DVec3;

/// Half-spaces `n · y ≥ h` (unit `n`) whose intersection holds an edge's
/// penumbra region.
#[derive(Debug, Clone, Default)]
pub struct RegionBound {
    planes: Vec<(DVec3, f64)>,
    /// The edge's two face planes when it only matters where they
    /// disagree (see [`RegionBound::with_dihedral`]), and the slack.
    dihedral: Option<([(DVec3, f64); 2], f64)>,
}

impl RegionBound {
    /// The bound of edge `v0 v1` against a light inside the convex hull of
    /// `corners`. `slack` (a distance) moves every plane outward, to cover
    /// rounding of the receivers' positions.
    pub fn new(v0: DVec3, v1: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        let mut generators: Vec<DVec3> = Vec::with_capacity(2 * corners.len());
        for v in [v0, v1] {
            for &x in corners {
                let d = v - x;
                if d.length_squared() > 0.0 && d.is_finite() {
                    generators.push(d.normalize());
                }
            }
        }
        let along = v1 - v0;
        // Facet normals: across two spanning directions, and (for flat
        // cones, where the region lies in a plane) within their plane,
        // perpendicular to either.
        let mut normals: Vec<DVec3> = Vec::new();
        let mut span = |a: DVec3, b: DVec3| {
            let n = a.cross(b);
            normals.extend([n, n.cross(a), n.cross(b)]);
        };
        for (k, &a) in generators.iter().enumerate() {
            for &b in &generators[k + 1..] {
                span(a, b);
            }
            span(along, a);
        }
        let mut planes = Vec::new();
        for n in normals {
            let len = n.length();
            if !(len > 1e-12) || !len.is_finite() {
                continue;
            }
            let n = n / len;
            for n in [n, -n] {
                // A facet of the cone: no generator points below it. The
                // two that span the plane give ±rounding, hence the
                // tolerance: a unit generator 1e-9 below tilts out of the
                // half-space by 1e-9 per unit of length, far inside
                // `slack` over any scene-sized distance.
                if generators.iter().all(|d| n.dot(*d) >= -1e-9) {
                    let h = n.dot(v0).min(n.dot(v1)) - slack;
                    planes.push((n, h));
                }
            }
        }
        RegionBound {
            planes,
            dihedral: None,
        }
    }

    /// A bound holding the regions of every edge inside the box
    /// `[lo, hi]` (a cluster of edges, for culling a tile against many
    /// edges at once): `conv(box) + cone{c_i − x_j}` over the box's
    /// corners `c_i` holds `a + t (a − x)` for every `a` in the box. Only
    /// valid planes are kept, not necessarily every facet (a looser bound
    /// is still conservative). For lights of at most four bounding
    /// corners (rects); otherwise no planes (the cost grows with the
    /// square of the corner count).
    pub fn around_box(lo: DVec3, hi: DVec3, corners: &[DVec3], slack: f64) -> RegionBound {
        if corners.len() > 4 || !(lo.cmple(hi).all()) {
            return RegionBound::default();
        }
        let points: Vec<DVec3> = (0..8)
            .map(|k| {
                let pick = |b: usize, l: f64, h: f64| if k >> b & 1 == 1 { h } else { l };
                DVec3::new(
                    pick(0, lo.x, hi.x),
                    pick(1, lo.y, hi.y),
                    pick(2, lo.z, hi.z),
                )
            })
            .collect();
        let mut generators: Vec<DVec3> = Vec::with_capacity(8 * corners.len());
        for &v in &points {
            for &x in corners {
                let d = v - x;
                if d.length_squared() > 0.0 && d.is_finite() {
                    generators.push(d.normalize());
                }
            }
        }
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        let mut normals: Vec<DVec3> = axes.to_vec();
        for (k, &a) in generators.iter().enumerate() {
            for &b in &generators[k + 1..] {
                normals.push(a.cross(b));
            }
            normals.extend(axes.iter().map(|&x| x.cross(a)));
        }
        let mut planes: Vec<(DVec3, f64)> = Vec::new();
        for n in normals {
            let len = n.length();
            if !(len > 1e-12) || !len.is_finite() {
                continue;
            }
            let n = n / len;
            for n in [n, -n] {
                // Same tolerance as `new`; near-duplicate normals add
                // nothing but cost.
                if planes.iter().any(|&(m, _)| m.dot(n) > 1.0 - 1e-9)
                    || !generators.iter().all(|d| n.dot(*d) >= -1e-9)
                {
                    continue;
                }
                let h = points
                    .iter()
                    .map(|&c| n.dot(c))
                    .fold(f64::INFINITY, f64::min)
                    - slack;
                planes.push((n, h));
            }
        }
        RegionBound {
            planes,
            dihedral: None,
        }
    }

    /// Also excludes receivers in front of both face planes or behind
    /// both (beyond `slack`): where the edge is not a silhouette, its
    /// multiplicity is 0 and it changes no counter.
    pub fn with_dihedral(mut self, faces: [(DVec3, f64); 2], slack: f64) -> RegionBound {
        self.dihedral = Some((faces, slack));
        self
    }

    /// Whether the dihedral test excludes every point whose signed
    /// distances to the two face planes lie in `[lo0, hi0]`, `[lo1, hi1]`.
    #[inline]
    fn dihedral_excludes(&self, d: [(f64, f64); 2]) -> bool {
        match self.dihedral {
            Some((_, slack)) => {
                let front = d.iter().all(|&(lo, _)| lo > slack);
                let behind = d.iter().all(|&(_, hi)| hi < -slack);
                front || behind
            }
            None => false,
        }
    }

    /// Whether `p` is outside the region (then the edge cannot change its
    /// counters).
    #[inline]
    pub fn excludes_point(&self, p: DVec3) -> bool {
        if let Some((faces, _)) = self.dihedral {
            let d = faces.map(|(n, h)| {
                let d = n.dot(p) - h;
                (d, d)
            });
            if self.dihedral_excludes(d) {
                return true;
            }
        }
        self.planes.iter().any(|&(n, h)| n.dot(p) < h)
    }

    /// Whether the whole box `[lo, hi]` is outside the region.
    pub fn excludes_box(&self, lo: DVec3, hi: DVec3) -> bool {
        let far = |n: DVec3, up: bool| {
            let pick = |c: f64, l: f64, h: f64| if (c >= 0.0) == up { h } else { l };
            DVec3::new(
                pick(n.x, lo.x, hi.x),
                pick(n.y, lo.y, hi.y),
                pick(n.z, lo.z, hi.z),
            )
        };
        if let Some((faces, _)) = self.dihedral {
            let d = faces.map(|(n, h)| (n.dot(far(n, false)) - h, n.dot(far(n, true)) - h));
            if self.dihedral_excludes(d) {
                return true;
            }
        }
        self.planes.iter().any(|&(n, h)| {
            // The box corner furthest along n.
            let far = DVec3::new(
                if n.x >= 0.0 { hi.x } else { lo.x },
                if n.y >= 0.0 { hi.y } else { lo.y },
                if n.z >= 0.0 { hi.z } else { lo.z },
            );
            n.dot(far) < h
        })
    }

    /// Number of bounding planes (0: no rejection possible).
    pub fn len(&self) -> usize {
        self.planes.len()
    }

    /// Whether there is no bounding plane.
    pub fn is_empty(&self) -> bool {
        self.planes.is_empty()
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

    /// Every point a light point sees through the edge, beyond it, is
    /// inside the bound; and the bound does reject far points.
    #[test]
    fn the_bound_holds_every_shadow_ray_and_rejects_others() {
        let corners = [
            DVec3::new(-1.0, 5.0, -1.0),
            DVec3::new(1.0, 5.0, -1.0),
            DVec3::new(1.0, 5.0, 1.0),
            DVec3::new(-1.0, 5.0, 1.0),
        ];
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
                    .planes
                    .iter()
                    .any(|&(n, h)| n.dot(p) < h - 1e-9 * (1.0 + p.length()));
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

    /// A cluster's bound never rejects a shadow-ray point of an edge
    /// inside its box, and does reject far points.
    #[test]
    fn cluster_bound_holds_its_edges_regions() {
        let corners = [
            DVec3::new(-1.0, 5.0, -1.0),
            DVec3::new(1.0, 5.0, -1.0),
            DVec3::new(1.0, 5.0, 1.0),
            DVec3::new(-1.0, 5.0, 1.0),
        ];
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
                    .planes
                    .iter()
                    .any(|&(n, h)| n.dot(p) < h - 1e-9 * (1.0 + p.length()));
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
        let big = RegionBound {
            planes: Vec::new(),
            dihedral: b.dihedral,
        };
        assert!(!big.excludes_box(DVec3::splat(-1.0), DVec3::splat(1.0)));
        assert!(big.excludes_box(DVec3::new(0.0, -5.0, -0.1), DVec3::new(1.0, -4.0, 0.1)));
    }
}
