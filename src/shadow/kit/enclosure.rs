//! Lights inside closed casters.
//!
//! A light inside (or touching) a closed caster surface is hidden from
//! every receiver outside that surface: every segment from the light to
//! such a receiver crosses it. The ray-traced techniques see that; the
//! silhouette-based ones do not (from inside a convex closed mesh no edge
//! is a silhouette, so its volume has no sides and its shadow is lost),
//! nor do maps rendered from a point inside the casters' bounds. Such
//! techniques refuse these scenes (their capability
//! [`crate::shadow::registry::Capabilities::enclosed_lights`]) rather than
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

/// The winding number of object `o` around `p`, times 4π.
fn winding(geometry: &SceneGeometry, o: usize, p: DVec3) -> f64 {
    let first = geometry.object_first_triangle[o] as usize;
    let end = geometry
        .object_first_triangle
        .get(o + 1)
        .map_or(geometry.triangles.len(), |&e| e as usize);
    geometry.triangles[first..end]
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| geometry.positions[i as usize].as_dvec3() - p);
            solid_angle(a, b, c)
        })
        .sum()
}

/// The first closed caster object (in scene order) each light is inside
/// of or touches while `eye` is outside it; other lights are not listed.
pub fn enclosed_lights(scene: &Scene, geometry: &SceneGeometry, eye: DVec3) -> Vec<EnclosedLight> {
    use std::f64::consts::PI;
    let mut found = Vec::new();
    let objects = scene.objects.len();
    for (k, light) in scene.lights.iter().enumerate() {
        let points = test_points(&light.shape);
        let enclosing = (0..objects).find(|&o| {
            scene.objects[o].cast_shadows
                && geometry.object_closed[o]
                && points
                    .iter()
                    .any(|&p| winding(geometry, o, p).abs() > 0.5 * PI)
                && winding(geometry, o, eye).abs() <= 3.0 * PI
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
