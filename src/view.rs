//! The camera as the renderer uses it: the contract's primary rays and the
//! matching reversed-Z, infinite-far projection for the rasterizer.

use crate::error::{Error, Result};
use crate::scene::Camera;
use glam::{DMat4, DVec3, DVec4, Vec3, Vec4};

/// A camera resolved for one image size.
#[derive(Debug, Clone, Copy)]
pub struct View {
    /// Eye position.
    pub eye: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit right vector.
    pub right: DVec3,
    /// Unit up vector, `cross(right, forward)`.
    pub up: DVec3,
    /// `tan(fov_y / 2)`.
    pub tan_half_fov: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Near-plane distance along `forward`.
    pub near: f64,
    view_projection: DMat4,
}

impl View {
    /// Resolves `camera` for a `width × height` image with the given near
    /// distance (> 0).
    pub fn new(camera: &Camera, width: u32, height: u32, near: f64) -> Result<View> {
        let eye = camera.eye.as_dvec3();
        let forward = (camera.target.as_dvec3() - eye).normalize_or_zero();
        let right = forward.cross(camera.up.as_dvec3()).normalize_or_zero();
        if forward == DVec3::ZERO || right == DVec3::ZERO {
            return Err(Error::param(
                "camera",
                "eye equals target, or up is parallel to the view direction",
            ));
        }
        if !(near > 0.0 && near.is_finite()) {
            return Err(Error::param("near", format!("{near} must be positive")));
        }
        let up = right.cross(forward);
        let tan_half_fov = (0.5 * (camera.fov_y_degrees as f64).to_radians()).tan();
        let aspect = width as f64 / height as f64;
        let view = DMat4::from_cols(
            DVec4::new(right.x, up.x, -forward.x, 0.0),
            DVec4::new(right.y, up.y, -forward.y, 0.0),
            DVec4::new(right.z, up.z, -forward.z, 0.0),
            DVec4::new(-right.dot(eye), -up.dot(eye), forward.dot(eye), 1.0),
        );
        // Reversed Z with an infinite far plane: z_clip = near * w_in,
        // w_clip = -z_view, so depth = near / distance along forward and
        // points at infinity (w_in = 0) land on depth 0.
        let projection = DMat4::from_cols(
            DVec4::new(1.0 / (tan_half_fov * aspect), 0.0, 0.0, 0.0),
            DVec4::new(0.0, 1.0 / tan_half_fov, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 0.0, -1.0),
            DVec4::new(0.0, 0.0, near, 0.0),
        );
        Ok(View {
            eye,
            forward,
            right,
            up,
            tan_half_fov,
            width,
            height,
            near,
            view_projection: projection * view,
        })
    }

    /// Unit direction of the primary ray through pixel `(i, j)`'s centre,
    /// exactly as the contract defines it.
    #[inline]
    pub fn primary_ray(&self, i: u32, j: u32) -> DVec3 {
        self.primary_ray_unnormalized(i, j).normalize()
    }

    /// The same ray's direction before normalisation (for hit points,
    /// which do not depend on its length).
    #[inline]
    pub fn primary_ray_unnormalized(&self, i: u32, j: u32) -> DVec3 {
        let (w, h) = (self.width as f64, self.height as f64);
        let x = (2.0 * (i as f64 + 0.5) / w - 1.0) * self.tan_half_fov * w / h;
        let y = (1.0 - 2.0 * (j as f64 + 0.5) / h) * self.tan_half_fov;
        self.forward + x * self.right + y * self.up
    }

    /// Clip-space position of a world point.
    #[inline]
    pub fn clip_point(&self, p: Vec3) -> Vec4 {
        (self.view_projection * p.as_dvec3().extend(1.0)).as_vec4()
    }

    /// Clip-space position of the point at infinity in direction `d`.
    #[inline]
    pub fn clip_direction(&self, d: Vec3) -> Vec4 {
        (self.view_projection * d.as_dvec3().extend(0.0)).as_vec4()
    }

    /// View-space depth along `forward` of a world point.
    #[inline]
    pub fn depth_of(&self, p: DVec3) -> f64 {
        (p - self.eye).dot(self.forward)
    }
}

/// A near distance suited to a scene: small against its extent so nothing
/// visible is clipped, yet far from zero (reversed-Z f32 depth keeps its
/// relative precision at any distance, so a tiny near costs nothing).
pub fn near_for_bounds(eye: Vec3, bounds: Option<(Vec3, Vec3)>) -> f64 {
    let extent = bounds.map_or(1.0, |(lo, hi)| {
        let far = [lo, hi]
            .iter()
            .map(|c| (c.as_dvec3() - eye.as_dvec3()).abs())
            .fold(DVec3::ZERO, |a, b| a.max(b));
        far.length().max((hi - lo).as_dvec3().length())
    });
    (extent * 1e-5).max(1e-9)
}
