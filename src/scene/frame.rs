//! The scene's local frame: a scene that sits far from the world origin
//! relative to its own size is moved, on loading, next to the origin.
//!
//! Positions are f32. At 1e5 units from the origin an f32 step is 1/128
//! unit, and every f32 difference and offset built on such coordinates
//! loses as much: the shadow-ray offset `1e-5 × max |p|` alone reaches a
//! whole unit there (measured: the quad scene translated by 1e5 lost most
//! of its penumbra, in the reference and every technique). Subtracting one
//! per-axis offset from every position brings the coordinates back to the
//! scene's own size, where f32 is as precise as for a scene at the origin.
//!
//! The offset is chosen from the camera, the lights and the objects'
//! translations before any mesh is placed, and each object's translation
//! is moved into the local frame before its mesh is transformed: a
//! built-in shape far away then rounds exactly as at the origin when the
//! offset equals the translation. A second pass after placing catches
//! meshes whose own (OBJ) vertices sit far from the origin.
//!
//! The subtraction is exact, so nothing of the scene as written is lost:
//! an axis is moved only when every coordinate on it lies within 1/16 of
//! its midpoint's magnitude of that midpoint, so every coordinate is in the
//! midpoint's binade or the one below and a multiple of half the
//! midpoint's f32 step; the offset is a multiple of twice that step, and
//! the differences, at most an eighth of the midpoint, fit in 24 bits.
//! Scenes near the origin are not touched (the same bits as before).
//! [`crate::scene::Scene::origin`] keeps the offset, and outputs that give
//! world positions (the position AOV, `penumbra info`) add it back.

use super::{Camera, Light, LightShape, Scene};
use glam::{DVec3, Vec3};

/// An axis is moved when its midpoint's magnitude exceeds this many times
/// its extent.
const FAR_RATIO: f64 = 8.0;

/// Per-axis bounds of the points `grow` is called with.
#[derive(Debug, Clone, Copy)]
struct Extent {
    lo: DVec3,
    hi: DVec3,
}

impl Extent {
    fn new() -> Self {
        Extent {
            lo: DVec3::INFINITY,
            hi: DVec3::NEG_INFINITY,
        }
    }

    fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p.as_dvec3());
        self.hi = self.hi.max(p.as_dvec3());
    }

    fn lights_and_camera(&mut self, camera: &Camera, lights: &[Light]) {
        for l in lights {
            match l.shape {
                LightShape::Rect { center, u, v, .. } => {
                    for p in [
                        center + u + v,
                        center + u - v,
                        center - u + v,
                        center - u - v,
                    ] {
                        self.grow(p);
                    }
                }
                LightShape::Sphere { center, radius } => {
                    self.grow(center - Vec3::splat(radius));
                    self.grow(center + Vec3::splat(radius));
                }
            }
        }
        self.grow(camera.eye);
        self.grow(camera.target);
    }

    fn offset(&self) -> DVec3 {
        DVec3::new(
            axis_offset(self.lo.x, self.hi.x),
            axis_offset(self.lo.y, self.hi.y),
            axis_offset(self.lo.z, self.hi.z),
        )
    }
}

/// The local origin of a scene from its camera, lights and the objects'
/// translations, before any mesh is placed.
pub fn local_origin(camera: &Camera, lights: &[Light], translations: &[Vec3]) -> DVec3 {
    let mut e = Extent::new();
    e.lights_and_camera(camera, lights);
    translations.iter().for_each(|&t| e.grow(t));
    e.offset()
}

/// `p − origin`, exact under the module's conditions.
pub fn shift(p: Vec3, origin: DVec3) -> Vec3 {
    (p.as_dvec3() - origin).as_vec3()
}

/// Moves the camera and the lights into the frame at `origin`.
pub fn shift_camera_and_lights(camera: &mut Camera, lights: &mut [Light], origin: DVec3) {
    if origin == DVec3::ZERO {
        return;
    }
    for l in lights {
        match &mut l.shape {
            LightShape::Rect { center, .. } | LightShape::Sphere { center, .. } => {
                *center = shift(*center, origin)
            }
        }
    }
    camera.eye = shift(camera.eye, origin);
    camera.target = shift(camera.target, origin);
}

/// The offset of one axis from its bounds: 0 unless the axis is far from
/// the origin relative to its extent.
fn axis_offset(lo: f64, hi: f64) -> f64 {
    if !(lo.is_finite() && hi.is_finite()) {
        return 0.0;
    }
    let mid = 0.5 * (lo + hi);
    if !(mid.abs() > FAR_RATIO * (hi - lo)) {
        return 0.0;
    }
    // f32 step at |mid|: 2^(exponent − 23); the offset is a multiple of
    // twice it.
    let step = 2.0 * 2f64.powi(mid.abs().log2().floor() as i32 - 23);
    (mid / step).round() * step
}

/// Moves `scene` next to the origin if it still sits far from it once
/// its meshes are placed (OBJ vertices far from the origin), adding the
/// offset to `scene.origin`.
pub fn recentre(scene: &mut Scene) {
    let mut e = Extent::new();
    for o in &scene.objects {
        o.mesh.positions.iter().for_each(|&p| e.grow(p));
    }
    e.lights_and_camera(&scene.camera, &scene.lights);
    let c = e.offset();
    if c == DVec3::ZERO {
        return;
    }
    for o in &mut scene.objects {
        o.mesh.positions.iter_mut().for_each(|p| *p = shift(*p, c));
    }
    shift_camera_and_lights(&mut scene.camera, &mut scene.lights, c);
    scene.origin += c;
}
