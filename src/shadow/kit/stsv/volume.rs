//! The soft textured shadow volume of an S-triangle (thesis §5.1.2) and
//! its planes (§5.1.3).
//!
//! For a light part `L` wholly on one side of the triangle's plane `H`
//! (normal `n` towards `L`), every point a light point `x ∈ L` sees
//! through a triangle point `y` is `p = x + s (y − x)`, `s ≥ 1`. It lies
//!
//! - **beyond `H`**: `n·(p − v0) = (1 − s) n·(x − v0) ≤ 0` (the front cap
//!   is the triangle itself);
//! - **inside each side plane**: the plane through an edge `ab`, turned
//!   about the edge's line until it touches `L` with `L` wholly on its
//!   outer side and the opposite corner on its inner side (the outer plane
//!   of the edge's penumbra wedge). With `P ≥ 0` inside, `P(x) ≤ 0 ≤
//!   P(y)` gives `P(p) = P(x) + s (P(y) − P(x)) ≥ P(y) ≥ 0`.
//!
//! In the cross-section about the edge's line (angle 0 towards the
//! opposite corner, `π/2` along `n`), `L` spans angles `[φ_lo, φ_hi] ⊂
//! [0, π]`; the tightest such plane is at `ψ = φ_lo`, inner normal
//! `k sin ψ − n cos ψ`. It exists when `φ_lo > 0`; otherwise (the light
//! reaches the triangle's plane on the triangle's side of the edge, or
//! touches the edge's line) the edge has no side plane and the volume is
//! bounded by the others only, still conservative.
//!
//! A light on both sides of `H` is split by `H` and each part gets its own
//! volume (the thesis's fix for the two-sided case). A sphere light
//! straddling `H` is bounded by its axis-aligned box, clipped by `H`.
//!
//! The volume to rasterize is the intersection of these half-spaces, each
//! moved outward by a margin, with the bounding box of the scene's
//! triangles (every receiver lies in it): a closed convex polyhedron with
//! finite vertices, built by clipping the box plane by plane, whose faces
//! share their vertices bit for bit (watertight for z-fail counting). The
//! margin covers the raster's rounding (1/256 px snapping, f32 depth) and
//! the distance between a receiver and its shadow-ray origin, so the
//! rasterized membership holds every receiver the exact planes hold.

use super::{STriangle, STriangles};
use crate::geom::SceneGeometry;
use crate::scene::Scene;
use crate::shadow::kit::rays::scene_diagonal;
use crate::shadow::kit::wedge_geometry::LightBound;
use crate::view::View;
use glam::DVec3;
use rayon::prelude::*;

/// A closed half-space `normal · x + offset ≥ 0` (`normal` of unit
/// length, so the value is the signed distance, positive inside).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    /// Unit inner normal.
    pub normal: DVec3,
    /// Offset.
    pub offset: f64,
}

impl HalfSpace {
    /// The half-space whose boundary passes through `point`, with inner
    /// normal `inner` (any length); `None` for a zero or non-finite one.
    pub fn through(point: DVec3, inner: DVec3) -> Option<HalfSpace> {
        let normal = inner.normalize_or_zero();
        let offset = -normal.dot(point);
        (normal != DVec3::ZERO && offset.is_finite()).then_some(HalfSpace { normal, offset })
    }

    /// Signed distance of `x` (positive inside).
    #[inline]
    pub fn distance(&self, x: DVec3) -> f64 {
        self.normal.dot(x) + self.offset
    }

    /// The same half-space moved outward by `by`.
    pub fn grown(&self, by: f64) -> HalfSpace {
        HalfSpace {
            normal: self.normal,
            offset: self.offset + by,
        }
    }
}

/// Where volumes are built: the box every receiver lies in, the outward
/// margin of the rasterized volumes, and the tolerance of the exact
/// point-in-STSV test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeParams {
    /// Lower corner of the bounding box of all triangles.
    pub lo: DVec3,
    /// Upper corner.
    pub hi: DVec3,
    /// Outward move of every rasterized plane (and twice that around the
    /// box).
    pub margin: f64,
    /// A point is inside the exact volume when every plane's signed
    /// distance is `≥ −tolerance`.
    pub tolerance: f64,
}

impl VolumeParams {
    /// The parameters for a scene seen through `view`.
    ///
    /// With `scale = D + max_i |coordinate_i|` (`D` the reference's scene
    /// diagonal): `tolerance = 1e-5 scale` covers the shadow-ray offset
    /// (`≤ 1e-5 scale`) and the f32 rounding of the per-sample test;
    /// `margin = 1e-4 scale + z_max (pixel / 32 + 1e-6)`, with `z_max`
    /// the farthest box corner from the eye and `pixel` the angle of one
    /// pixel, is ten times that plus eight times the 1/256 px snapping and
    /// the f32 depth rounding at the farthest receiver.
    pub fn new(scene: &Scene, geometry: &SceneGeometry, view: &View) -> VolumeParams {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for p in &geometry.positions {
            lo = lo.min(p.as_dvec3());
            hi = hi.max(p.as_dvec3());
        }
        if !(lo.x <= hi.x) {
            lo = DVec3::ZERO;
            hi = DVec3::ZERO;
        }
        let coords = lo.abs().max(hi.abs()).max_element();
        let scale = scene_diagonal(scene, geometry) + coords;
        let scale = if scale > 0.0 && scale.is_finite() {
            scale
        } else {
            1.0
        };
        let mut z_max: f64 = 0.0;
        for k in 0..8 {
            let pick = |bit: usize, a: f64, b: f64| if k >> bit & 1 == 1 { b } else { a };
            let c = DVec3::new(
                pick(0, lo.x, hi.x),
                pick(1, lo.y, hi.y),
                pick(2, lo.z, hi.z),
            );
            z_max = z_max.max((c - view.eye).length());
        }
        let pixel = 2.0 * view.tan_half_fov / f64::from(view.height.max(1));
        let margin = 1e-4 * scale + z_max * (pixel / 32.0 + 1e-6);
        VolumeParams {
            lo,
            hi,
            margin: if margin.is_finite() { margin } else { scale },
            tolerance: 1e-5 * scale,
        }
    }
}

/// One soft textured shadow volume.
#[derive(Debug, Clone, PartialEq)]
pub struct Stsv {
    /// Index of its S-triangle in [`STriangles::list`].
    pub s_triangle: u32,
    /// `+1`: cast by the light part on the side the triangle's normal
    /// points to (the volume lies on the other side); `−1`: the other part.
    pub side: i8,
    /// The exact planes (front cap first, then the side planes that
    /// exist): a point is inside when it is inside all of them.
    pub planes: Vec<HalfSpace>,
    /// Vertices of the rasterized polyhedron (grown planes ∩ box).
    pub vertices: Vec<DVec3>,
    /// Its triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl Stsv {
    /// The point-in-STSV test (§5.1.3), exact in f64: every plane's signed
    /// distance at `p` is at least `−tolerance`.
    #[inline]
    pub fn contains(&self, p: DVec3, tolerance: f64) -> bool {
        self.planes.iter().all(|h| h.distance(p) >= -tolerance)
    }
}

/// The part of the light on the positive side of a plane.
#[derive(Debug, Clone)]
enum LightPart {
    /// The convex hull of points (a rect, or a rect or box clipped).
    Points(Vec<DVec3>),
    /// A whole sphere.
    Ball { center: DVec3, radius: f64 },
}

/// `points` (a convex polygon's cycle, or any point set whose hull is the
/// part) clipped to `h(x) = n·(x − a) ≥ 0`, edges given as index pairs.
fn clip_points(points: &[DVec3], edges: &[(usize, usize)], n: DVec3, a: DVec3) -> Vec<DVec3> {
    let h = |x: DVec3| n.dot(x - a);
    let mut out: Vec<DVec3> = points.iter().copied().filter(|&x| h(x) >= 0.0).collect();
    for &(i, j) in edges {
        let (p, q) = (points[i], points[j]);
        let (hp, hq) = (h(p), h(q));
        if (hp > 0.0 && hq < 0.0) || (hp < 0.0 && hq > 0.0) {
            out.push(p + (q - p) * (hp / (hp - hq)));
        }
    }
    out
}

/// The part of `light` with `n·(x − a) > 0` somewhere, bounded: `None`
/// when no light point is strictly on that side (points on the plane
/// cannot shadow through it).
fn light_part(light: &LightBound, n: DVec3, a: DVec3) -> Option<LightPart> {
    let h = |x: DVec3| n.dot(x - a);
    match *light {
        LightBound::Rect(frame) => {
            let corners = frame.corners();
            let hs = corners.map(h);
            if !hs.iter().any(|&v| v > 0.0) {
                return None;
            }
            if hs.iter().all(|&v| v >= 0.0) {
                return Some(LightPart::Points(corners.to_vec()));
            }
            let cycle = [(0, 1), (1, 2), (2, 3), (3, 0)];
            Some(LightPart::Points(clip_points(&corners, &cycle, n, a)))
        }
        LightBound::Sphere { center, radius } => {
            let hc = h(center);
            if !(hc + radius > 0.0) {
                return None;
            }
            if hc - radius >= 0.0 {
                return Some(LightPart::Ball { center, radius });
            }
            // Straddling: the bounding box's part, a conservative hull.
            let corners: Vec<DVec3> = (0..8)
                .map(|k| {
                    let s = |bit: usize| if k >> bit & 1 == 1 { radius } else { -radius };
                    center + DVec3::new(s(0), s(1), s(2))
                })
                .collect();
            let mut edges = Vec::new();
            for i in 0..8usize {
                for bit in 0..3 {
                    if i >> bit & 1 == 0 {
                        edges.push((i, i | 1 << bit));
                    }
                }
            }
            Some(LightPart::Points(clip_points(&corners, &edges, n, a)))
        }
    }
}

/// The side plane through edge `a → b` (opposite corner `c`) for a light
/// part on the side of unit normal `n`; `None` when none exists.
fn side_plane(a: DVec3, b: DVec3, c: DVec3, n: DVec3, part: &LightPart) -> Option<HalfSpace> {
    let e = (b - a).normalize_or_zero();
    if e == DVec3::ZERO {
        return None;
    }
    let mut k = n.cross(e).normalize_or_zero();
    if k.dot(c - a) < 0.0 {
        k = -k;
    }
    if k == DVec3::ZERO || !(k.dot(c - a) > 0.0) {
        return None;
    }
    let phi_lo = match part {
        LightPart::Points(points) => points
            .iter()
            .map(|&x| {
                let y = x - a;
                // Points of the part are on the positive side; clamping
                // keeps a clipped point rounded just below the plane at
                // angle 0 or π instead of wrapping to −π.
                n.dot(y).max(0.0).atan2(k.dot(y))
            })
            .fold(f64::INFINITY, f64::min),
        LightPart::Ball { center, radius } => {
            let y = *center - a;
            let (hn, hk) = (n.dot(y), k.dot(y));
            let d = hn.hypot(hk);
            if !(d > *radius) {
                return None;
            }
            hn.atan2(hk) - (radius / d).asin()
        }
    };
    if !(phi_lo > 0.0 && phi_lo < std::f64::consts::PI) {
        return None;
    }
    HalfSpace::through(a, k * phi_lo.sin() - n * phi_lo.cos())
}

/// The exact planes of `tri`'s volumes for `light`, per side (`+1`, `−1`)
/// the light reaches: front cap (the triangle's plane, inside beyond it)
/// first, then the side planes that exist. Empty for a triangle without
/// area or a light with no point off its plane.
pub fn stsv_planes(tri: &STriangle, light: &LightBound) -> Vec<(i8, Vec<HalfSpace>)> {
    let [v0, v1, v2] = tri.corners;
    let unit = tri.frame.normal.normalize_or_zero();
    if unit == DVec3::ZERO || !unit.is_finite() {
        return Vec::new();
    }
    let mut out = Vec::new();
    for side in [1i8, -1] {
        let n = unit * f64::from(side);
        let Some(part) = light_part(light, n, v0) else {
            continue;
        };
        let Some(cap) = HalfSpace::through(v0, -n) else {
            continue;
        };
        let mut planes = vec![cap];
        for (a, b, c) in [(v0, v1, v2), (v1, v2, v0), (v2, v0, v1)] {
            planes.extend(side_plane(a, b, c, n, &part));
        }
        out.push((side, planes));
    }
    out
}

/// Every S-triangle's volumes for `light`, in S-triangle order (`+1`
/// before `−1`); built in parallel, the same list for any thread count.
pub fn build_volumes(stris: &STriangles, light: &LightBound, params: &VolumeParams) -> Vec<Stsv> {
    let per: Vec<Vec<Stsv>> = stris
        .list
        .par_iter()
        .enumerate()
        .map(|(s, tri)| {
            stsv_planes(tri, light)
                .into_iter()
                .filter_map(|(side, planes)| {
                    let m = params.margin;
                    let mut poly = Polyhedron::cuboid(
                        params.lo - DVec3::splat(2.0 * m),
                        params.hi + DVec3::splat(2.0 * m),
                    );
                    for h in &planes {
                        // A failed clip leaves the polyhedron unclipped by
                        // this plane: larger, still conservative.
                        poly.clip(&h.grown(m));
                    }
                    let (vertices, triangles) = poly.mesh();
                    (!triangles.is_empty()).then_some(Stsv {
                        s_triangle: s as u32,
                        side,
                        planes,
                        vertices,
                        triangles,
                    })
                })
                .collect()
        })
        .collect();
    per.into_iter().flatten().collect()
}

/// Bit pattern of a point, for exact identity.
fn key(p: DVec3) -> [u64; 3] {
    p.to_array().map(f64::to_bits)
}

/// A convex polyhedron as its faces, each a convex polygon counter-
/// clockwise seen from outside; faces share vertices bit for bit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Polyhedron {
    faces: Vec<Vec<DVec3>>,
}

impl Polyhedron {
    /// The box `[lo, hi]`.
    pub(crate) fn cuboid(lo: DVec3, hi: DVec3) -> Polyhedron {
        let c = |i: usize| {
            DVec3::new(
                if i & 1 == 1 { hi.x } else { lo.x },
                if i & 2 == 2 { hi.y } else { lo.y },
                if i & 4 == 4 { hi.z } else { lo.z },
            )
        };
        // Each face's corners in a cycle, outward normal per face.
        let faces = [
            ([0, 4, 6, 2], -DVec3::X),
            ([1, 3, 7, 5], DVec3::X),
            ([0, 1, 5, 4], -DVec3::Y),
            ([2, 6, 7, 3], DVec3::Y),
            ([0, 2, 3, 1], -DVec3::Z),
            ([4, 5, 7, 6], DVec3::Z),
        ];
        Polyhedron {
            faces: faces
                .iter()
                .map(|(ids, out)| {
                    let mut f: Vec<DVec3> = ids.iter().map(|&i| c(i)).collect();
                    if newell(&f).dot(*out) < 0.0 {
                        f.reverse();
                    }
                    f
                })
                .collect(),
        }
    }

    /// Keeps the part with `h.distance ≥ 0`. Returns false (and changes
    /// nothing) when rounding made the cut inconsistent, which leaves the
    /// polyhedron larger: still conservative.
    pub(crate) fn clip(&mut self, h: &HalfSpace) -> bool {
        let d = |p: DVec3| h.distance(p);
        let all = || self.faces.iter().flatten();
        if !all().any(|&p| d(p) < 0.0) {
            return true;
        }
        if !all().any(|&p| d(p) > 0.0) {
            self.faces.clear();
            return true;
        }
        let mut faces = Vec::with_capacity(self.faces.len() + 1);
        // Per cut face: (entry, exit) of its boundary walk; the cap walks
        // each such edge the other way round (entry → exit).
        let mut links: Vec<(DVec3, DVec3)> = Vec::new();
        for face in &self.faces {
            let mut kept = Vec::with_capacity(face.len() + 1);
            let (mut entry, mut exit, mut crossings) = (None, None, 0);
            for (i, &p) in face.iter().enumerate() {
                let q = face[(i + 1) % face.len()];
                let (dp, dq) = (d(p), d(q));
                if dp >= 0.0 {
                    kept.push(p);
                }
                if (dp >= 0.0) != (dq >= 0.0) {
                    let x = cut(p, dp, q, dq);
                    kept.push(x);
                    crossings += 1;
                    if dp >= 0.0 {
                        exit = Some(x);
                    } else {
                        entry = Some(x);
                    }
                }
            }
            if crossings > 2 {
                return false;
            }
            kept.dedup_by(|a, b| key(*a) == key(*b));
            while kept.len() > 1 && key(kept[0]) == key(kept[kept.len() - 1]) {
                kept.pop();
            }
            if kept.len() >= 3 {
                faces.push(kept);
            }
            if let (Some(en), Some(ex)) = (entry, exit) {
                if key(en) != key(ex) {
                    links.push((en, ex));
                }
            }
        }
        // Chain the cut edges into the cap polygon.
        let Some(&first) = links.first() else {
            return false;
        };
        let mut cap = vec![first.0];
        let mut at = first.1;
        while key(at) != key(first.0) {
            let Some(&(en, ex)) = links.iter().find(|(en, _)| key(*en) == key(at)) else {
                return false;
            };
            if cap.len() > links.len() {
                return false;
            }
            cap.push(en);
            at = ex;
        }
        if cap.len() != links.len() {
            return false;
        }
        if cap.len() >= 3 {
            faces.push(cap);
        }
        self.faces = faces;
        true
    }

    /// Indexed vertices (deduplicated by bits) and fan triangles,
    /// counter-clockwise seen from outside.
    pub(crate) fn mesh(&self) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut vertices: Vec<DVec3> = Vec::new();
        let mut ids = std::collections::HashMap::new();
        let mut triangles = Vec::new();
        for face in &self.faces {
            let idx: Vec<u32> = face
                .iter()
                .map(|&p| {
                    *ids.entry(key(p)).or_insert_with(|| {
                        vertices.push(p);
                        (vertices.len() - 1) as u32
                    })
                })
                .collect();
            for i in 1..idx.len().saturating_sub(1) {
                triangles.push([idx[0], idx[i], idx[i + 1]]);
            }
        }
        (vertices, triangles)
    }
}

/// Where edge `p q` crosses the plane (`dp`, `dq` of opposite classes),
/// computed from the edge's endpoints in a fixed order so that the two
/// faces sharing the edge get the same bits.
fn cut(p: DVec3, dp: f64, q: DVec3, dq: f64) -> DVec3 {
    if dp == 0.0 {
        return p;
    }
    if dq == 0.0 {
        return q;
    }
    let (p, dp, q, dq) = if key(p) <= key(q) {
        (p, dp, q, dq)
    } else {
        (q, dq, p, dp)
    };
    p + (q - p) * (dp / (dp - dq))
}

/// Newell's normal of a polygon (area-weighted, any winding).
fn newell(points: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (i, p) in points.iter().enumerate() {
        let q = points[(i + 1) % points.len()];
        n += p.cross(q);
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shadow::kit::light_frame::RectFrame;
    use std::collections::HashMap;

    use crate::shadow::kit::stsv::test_triangle as tri;

    struct Rng(u64);
    impl Rng {
        fn f(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Every directed edge used once and its reverse once: closed,
    /// consistently oriented.
    fn assert_closed(triangles: &[[u32; 3]]) {
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        assert!(edges.values().all(|&v| v == 0), "{edges:?}");
    }

    /// Shadow points of random light and triangle points, inside.
    fn check_conservative(t: &STriangle, light: &LightBound, rng: &mut Rng) {
        let vols = stsv_planes(t, light);
        let [a, b, c] = t.corners;
        for _ in 0..4000 {
            let x = match light {
                LightBound::Rect(f) => {
                    f.center + f.u * (2.0 * rng.f() - 1.0) + f.v * (2.0 * rng.f() - 1.0)
                }
                LightBound::Sphere { center, radius } => loop {
                    let d = DVec3::new(rng.f(), rng.f(), rng.f()) * 2.0 - 1.0;
                    if d.length() <= 1.0 {
                        break *center + d * *radius;
                    }
                },
            };
            let (mut u, mut v) = (rng.f(), rng.f());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let y = a + (b - a) * u + (c - a) * v;
            let p = x + (y - x) * (1.0 + 5.0 * rng.f());
            let inside = vols
                .iter()
                .any(|(_, planes)| planes.iter().all(|h| h.distance(p) >= -1e-9));
            assert!(inside, "{p} from {x} through {y}");
        }
    }

    #[test]
    fn volumes_hold_every_shadow_point() {
        let mut rng = Rng(9);
        let t = tri([
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.5, 1.2, -0.7),
            DVec3::new(-0.2, 0.8, 1.3),
        ]);
        let rect = LightBound::Rect(RectFrame::new(
            DVec3::new(0.3, 4.0, 0.2),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.2, 0.8),
        ));
        let sphere = LightBound::Sphere {
            center: DVec3::new(-0.5, 3.0, 0.5),
            radius: 0.7,
        };
        // Straddling the triangle's plane: two volumes.
        let straddle = LightBound::Rect(RectFrame::new(
            DVec3::new(4.0, 1.0, 0.0),
            DVec3::new(0.0, 1.5, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
        ));
        let straddle_ball = LightBound::Sphere {
            center: DVec3::new(0.0, 1.0, 4.0),
            radius: 1.0,
        };
        for (light, sides) in [(rect, 1), (sphere, 1), (straddle, 2), (straddle_ball, 2)] {
            assert_eq!(stsv_planes(&t, &light).len(), sides);
            check_conservative(&t, &light, &mut rng);
        }
    }

    #[test]
    fn side_planes_are_tight() {
        // A light far above a horizontal triangle: three side planes, each
        // touching the light.
        let t = tri([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -1.0),
        ]);
        let frame = RectFrame::new(DVec3::new(0.2, 3.0, -0.2), DVec3::X * 0.5, DVec3::Z * 0.5);
        let vols = stsv_planes(&t, &LightBound::Rect(frame));
        assert_eq!(vols.len(), 1);
        let planes = &vols[0].1;
        assert_eq!(planes.len(), 4);
        for h in &planes[1..] {
            let worst = frame
                .corners()
                .iter()
                .map(|&x| h.distance(x))
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(worst.abs() < 1e-12, "{worst}");
        }
    }

    #[test]
    fn raster_mesh_is_closed_and_contains_the_exact_volume() {
        let t = tri([
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.5, 1.2, -0.7),
            DVec3::new(-0.2, 0.8, 1.3),
        ]);
        let stris = STriangles { list: vec![t] };
        let params = VolumeParams {
            lo: DVec3::splat(-5.0),
            hi: DVec3::splat(5.0),
            margin: 1e-3,
            tolerance: 1e-5,
        };
        let light = LightBound::Rect(RectFrame::new(
            DVec3::new(3.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
        ));
        let vols = build_volumes(&stris, &light, &params);
        assert_eq!(vols.len(), 2);
        let mut rng = Rng(4);
        for v in &vols {
            assert_closed(&v.triangles);
            // Every mesh face's plane has the whole mesh behind it, and
            // random points of the exact volume are inside every face.
            let faces: Vec<HalfSpace> = v
                .triangles
                .iter()
                .filter_map(|t| {
                    let [a, b, c] = t.map(|i| v.vertices[i as usize]);
                    HalfSpace::through(a, -(b - a).cross(c - a))
                })
                .collect();
            for _ in 0..2000 {
                let p = DVec3::new(rng.f(), rng.f(), rng.f()) * 10.0 - 5.0;
                if v.contains(p, 0.0) {
                    assert!(faces.iter().all(|h| h.distance(p) >= 0.0), "{p}");
                }
            }
        }
    }

    #[test]
    fn degenerate_cases_do_not_panic() {
        let flat = tri([DVec3::ZERO, DVec3::X, DVec3::X * 2.0]);
        let light = LightBound::Rect(RectFrame::new(DVec3::Y, DVec3::X, DVec3::Z));
        assert!(stsv_planes(&flat, &light).is_empty());
        // A light in the triangle's plane: nothing off the plane.
        let t = tri([DVec3::ZERO, DVec3::X, -DVec3::Z]);
        let coplanar = LightBound::Rect(RectFrame::new(DVec3::X * 3.0, DVec3::X, DVec3::Z));
        assert!(stsv_planes(&t, &coplanar).is_empty());
        // A light touching the plane along one edge, and a tangent sphere.
        let touching = LightBound::Rect(RectFrame::new(
            DVec3::new(0.3, 1.0, -0.3),
            DVec3::Y,
            DVec3::Z,
        ));
        let tangent = LightBound::Sphere {
            center: DVec3::new(0.3, 1.0, -0.3),
            radius: 1.0,
        };
        for light in [touching, tangent] {
            let v = stsv_planes(&t, &light);
            assert!(!v.is_empty());
            for (_, planes) in &v {
                assert!(planes
                    .iter()
                    .all(|h| h.normal.is_finite() && h.offset.is_finite()));
            }
        }
    }
}
