//! Lights inside closed casters.
//!
//! A light inside (or touching) a closed caster surface is hidden from
//! every receiver outside that surface: every segment from the light to
//! such a receiver crosses it. The ray-traced techniques see that; the
//! silhouette-based ones do not (from inside a convex closed mesh no edge
//! is a silhouette, so its volume has no sides and its shadow is lost),
//! nor do maps rendered from a point inside the casters' bounds. Such
//! techniques refuse these scenes (their capability
//! [`crate::shadow::technique::Capabilities::enclosed_lights`]) rather than
//! give a silently different image — unless the eye is inside the same
//! closed caster (a light in a closed room seen from inside it): every
//! visible receiver is then inside it too, where the caster's own edges
//! shadow exactly what they should (measured: DCS equals the reference in
//! such a room).
//!
//! The test is the generalised winding number of each closed caster
//! object around a few points of the light (a rect light's centre and
//! corners, a sphere light's centre and its six axis extremes): the sum of
//! the signed solid angles its triangles subtend (Van Oosterom & Strackee
//! 1983), `±4π` inside a closed surface, `0` outside, `±2π` on it. It needs
//! no ray direction, so no tie rule; a light point with `|w| > π/2` counts
//! as inside or touching, the eye with `|w| > 3π` as inside.

use crate::geom::SceneGeometry;
use crate::scene::{LightShape, Scene};
use glam::DVec3;
use rayon::prelude::*;

/// A light inside or touching a closed caster.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnclosedLight {
    /// The light's index in the scene.
    pub light: usize,
    /// The enclosing object's name.
    pub object: String,
}

/// The test points of a light: what must all be outside every closed
/// caster for silhouettes to see the light's shadows.
fn test_points(shape: &LightShape) -> Vec<DVec3> {
    match *shape {
        LightShape::Rect { center, u, v, .. } => {
            let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
            vec![c, c + u + v, c + u - v, c - u + v, c - u - v]
        }
        LightShape::Sphere { center, radius } => {
            let (c, r) = (center.as_dvec3(), f64::from(radius));
            let mut p = vec![c];
            for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                p.push(c + axis * r);
                p.push(c - axis * r);
            }
            p
        }
    }
}

/// The solid angle triangle `(a, b, c)` subtends from the origin, signed
/// by its winding (Van Oosterom & Strackee).
fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * num.atan2(den)
}

/// Object `o`'s triangles.
fn object_triangles(geometry: &SceneGeometry, o: usize) -> &[[u32; 3]] {
    &geometry.triangles[geometry.object_triangle_range(o)]
}

/// The winding number of object `o` around `p`, times 4π: 0 without a
/// sum when `p` is outside the box `bounds` of its vertices (a closed
/// surface winds zero times around any point outside its convex hull).
/// The sum runs in parallel over fixed chunks added in order, so it is
/// the same for any thread count.
fn winding(geometry: &SceneGeometry, o: usize, bounds: (DVec3, DVec3), p: DVec3) -> f64 {
    if p.cmplt(bounds.0).any() || p.cmpgt(bounds.1).any() {
        return 0.0;
    }
    let partial: Vec<f64> = object_triangles(geometry, o)
        .par_chunks(4096)
        .map(|chunk| {
            chunk
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| geometry.positions[i as usize].as_dvec3() - p);
                    solid_angle(a, b, c)
                })
                .sum::<f64>()
        })
        .collect();
    partial.iter().sum()
}

/// The box of object `o`'s vertices (those its triangles use).
fn object_bounds(geometry: &SceneGeometry, o: usize) -> (DVec3, DVec3) {
    object_triangles(geometry, o)
        .par_chunks(4096)
        .map(|chunk| {
            let mut b = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for &i in chunk.iter().flatten() {
                let p = geometry.positions[i as usize].as_dvec3();
                b = (b.0.min(p), b.1.max(p));
            }
            b
        })
        .reduce(
            || (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        )
}

/// The first closed caster object (in scene order) each light is inside
/// of or touches while `eye` is outside it; other lights are not listed.
pub fn enclosed_lights(scene: &Scene, geometry: &SceneGeometry, eye: DVec3) -> Vec<EnclosedLight> {
    use std::f64::consts::PI;
    let mut found = Vec::new();
    let objects = scene.objects.len();
    // Bounds of the closed casters only, computed on first need.
    let mut bounds: Vec<Option<(DVec3, DVec3)>> = vec![None; objects];
    for (k, light) in scene.lights.iter().enumerate() {
        let points = test_points(&light.shape);
        let enclosing = (0..objects).find(|&o| {
            if !(scene.objects[o].cast_shadows && geometry.object_closed[o]) {
                return false;
            }
            let b = *bounds[o].get_or_insert_with(|| object_bounds(geometry, o));
            points
                .iter()
                .any(|&p| winding(geometry, o, b, p).abs() > 0.5 * PI)
                && winding(geometry, o, b, eye).abs() <= 3.0 * PI
        });
        if let Some(o) = enclosing {
            found.push(EnclosedLight {
                light: k,
                object: scene.objects[o].name.clone(),
            });
        }
    }
    found
}

/// A shadow caster that reaches into a light: one of its triangles
/// crosses a rect light's rectangle or enters a sphere light's ball.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReachedLight {
    /// The light's index in the scene.
    pub light: usize,
    /// The object's name.
    pub object: String,
}

/// The first caster (in triangle order) reaching into each light; lights
/// no caster reaches are not listed.
///
/// Techniques that count occluders from the light's centre (DCS's start
/// count, its edges clipped at the light) see a caster part beyond the
/// light's surface, or inside its ball, as the shadow rays never do: the
/// reference's segments end on the light. A triangle tangent to a sphere
/// light's ball is not listed; a vertex or an edge on a rect light's
/// rectangle is (an edge lying in the light's plane is clipped to nothing
/// there while its faces still end on the light: a fuzz campaign found
/// DCS wrong on such quads), and so is a triangle in the light's plane
/// overlapping the rectangle.
pub fn reached_lights(scene: &Scene, geometry: &SceneGeometry) -> Vec<ReachedLight> {
    let mut found = Vec::new();
    for (k, light) in scene.lights.iter().enumerate() {
        let reaches: Box<dyn Fn([DVec3; 3]) -> bool + Sync> = match light.shape {
            LightShape::Rect { center, u, v, .. } => {
                let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
                Box::new(move |t| triangle_crosses_rect(t, c, u, v))
            }
            LightShape::Sphere { center, radius } => {
                let (c, r) = (center.as_dvec3(), f64::from(radius));
                Box::new(move |t| closest_point_on_triangle(c, t).distance(c) < r)
            }
        };
        // The first in triangle order, whatever the thread count.
        let hit = geometry
            .triangles
            .par_iter()
            .enumerate()
            .find_first(|&(t, tri)| {
                let o = geometry.triangle_object[t] as usize;
                scene.objects.get(o).is_some_and(|o| o.cast_shadows)
                    && reaches(tri.map(|i| geometry.positions[i as usize].as_dvec3()))
            });
        if let Some((t, _)) = hit {
            found.push(ReachedLight {
                light: k,
                object: scene.objects[geometry.triangle_object[t] as usize]
                    .name
                    .clone(),
            });
        }
    }
    found
}

/// Whether triangle `t` crosses the rectangle `c ± u ± v` (its interior
/// meets the rectangle's plane inside the rectangle), or lies in that
/// plane overlapping it.
fn triangle_crosses_rect(t: [DVec3; 3], c: DVec3, u: DVec3, v: DVec3) -> bool {
    let n = u.cross(v);
    let d = t.map(|p| (p - c).dot(n));
    // The rectangle's own coordinates of a point in its plane: `u` and
    // `v` need not be orthogonal, so through their Gram matrix.
    let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
    let det = uu * vv - uv * uv;
    if !(det > 0.0) {
        return false;
    }
    let st = |p: DVec3| {
        let (a, b) = ((p - c).dot(u), (p - c).dot(v));
        [(a * vv - b * uv) / det, (b * uu - a * uv) / det]
    };
    if d.iter().all(|&x| x == 0.0) {
        return convex_polygons_overlap(
            &t.map(st),
            &[[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]],
        );
    }
    let (lo, hi) = (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]));
    if !(lo <= 0.0 && hi >= 0.0) {
        return false;
    }
    if !(lo < 0.0 && hi > 0.0) {
        // Touching the plane from one side: a vertex or an edge in it. An
        // edge lying in the light (a quad standing on the light's plane
        // under it) is clipped to nothing at the light, yet its faces
        // still end there: counted wrongly, so it reaches in too.
        let on: Vec<DVec3> = (0..3).filter(|&i| d[i] == 0.0).map(|i| t[i]).collect();
        return match on.as_slice() {
            [p] => {
                let [x, y] = st(*p);
                x.abs() <= 1.0 && y.abs() <= 1.0
            }
            [a, b] => segment_meets_square(st(*a), st(*b)),
            _ => false,
        };
    }
    // The segment where the triangle meets the plane: its two edges (or
    // an edge and a vertex) with ends on both sides.
    let mut ends = Vec::with_capacity(2);
    for i in 0..3 {
        let (a, b) = (i, (i + 1) % 3);
        if d[a] == 0.0 {
            ends.push(t[a]);
        } else if (d[a] < 0.0) != (d[b] < 0.0) && d[b] != 0.0 {
            ends.push(t[a] + (t[b] - t[a]) * (d[a] / (d[a] - d[b])));
        }
    }
    let [Some(&q0), Some(&q1)] = [ends.first(), ends.get(1)] else {
        return false;
    };
    segment_meets_square(st(q0), st(q1))
}

/// Whether segment `a → b` meets the square `[-1, 1]²` (Liang–Barsky).
fn segment_meets_square(a: [f64; 2], b: [f64; 2]) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..2 {
        let (p, q) = (a[axis], b[axis] - a[axis]);
        if q == 0.0 {
            if !(-1.0..=1.0).contains(&p) {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((-1.0 - p) / q, (1.0 - p) / q);
        let (enter, leave) = if ta < tb { (ta, tb) } else { (tb, ta) };
        t0 = t0.max(enter);
        t1 = t1.min(leave);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Whether two convex polygons (either winding) overlap with positive
/// area or touch: the separating axis test over both polygons' edges.
fn convex_polygons_overlap(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    let separated = |poly: &[[f64; 2]], other: &[[f64; 2]]| {
        (0..poly.len()).any(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let axis = [q[1] - p[1], p[0] - q[0]];
            let proj = |s: &[[f64; 2]]| {
                s.iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                        let d = x[0] * axis[0] + x[1] * axis[1];
                        (lo.min(d), hi.max(d))
                    })
            };
            let ((a0, a1), (b0, b1)) = (proj(poly), proj(other));
            a1 <= b0 || b1 <= a0
        })
    };
    !separated(a, b) && !separated(b, a)
}

/// The point of triangle `t` closest to `p` (Ericson, *Real-Time
/// Collision Detection*, 5.1.5).
fn closest_point_on_triangle(p: DVec3, t: [DVec3; 3]) -> DVec3 {
    let [a, b, c] = t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}
