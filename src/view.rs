//! Views for the rasterizer: the contract's camera (primary rays and the
//! matching reversed-Z, infinite-far projection), and any other perspective
//! frustum, e.g. one from a point on a light (`shadow::light_view`).

use crate::error::{Error, Result};
use crate::scene::Camera;
use glam::{DMat4, DVec2, DVec3, DVec4, Vec3, Vec4};

/// How wide a view's frustum is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Extent {
    /// Symmetric about the forward axis: vertical field of view in degrees,
    /// in (0, 180); the horizontal one follows from the texel aspect
    /// `width / height` (square texels), as for the contract's camera.
    FovY {
        /// Vertical field of view in degrees.
        degrees: f64,
    },
    /// Off-axis: the image rectangle on the near plane, in world units
    /// along `right` (left < right) and `up` (bottom < top). Texels are
    /// square only if the rectangle has the image's aspect.
    Window {
        /// Left edge along `right`.
        left: f64,
        /// Right edge along `right`.
        right: f64,
        /// Bottom edge along `up`.
        bottom: f64,
        /// Top edge along `up`.
        top: f64,
    },
}

/// The image rectangle at unit distance along `forward`: tangents of the
/// frustum's side planes, `x` along `right`, `y` along `up`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// Smallest `x / depth` in the frustum.
    pub left: f64,
    /// Largest `x / depth`.
    pub right: f64,
    /// Smallest `y / depth`.
    pub bottom: f64,
    /// Largest `y / depth`.
    pub top: f64,
}

/// A perspective view resolved for one image size.
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
    /// Symmetric views: `tan(fov_y / 2)`. Off-axis views: the smallest
    /// `t` such that the symmetric frustum `|y| <= t`, `|x| <= t · width /
    /// height` contains [`View::window`], so that bounds derived from it
    /// (the near rectangle, a texel's angle) stay conservative.
    pub tan_half_fov: f64,
    /// The frustum at unit distance (for symmetric views, `±tan_half_fov ·
    /// width / height` by `±tan_half_fov`).
    pub window: Window,
    /// Whether the frustum is the symmetric one of [`Extent::FovY`]; the
    /// G-buffer resolve builds its rays from `tan_half_fov` and supports
    /// only such views.
    pub symmetric: bool,
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
        let extent = Extent::FovY {
            degrees: camera.fov_y_degrees as f64,
        };
        View::resolve(eye, forward, right, extent, width, height, near)
    }

    /// A view from `eye` looking along `forward` (any length > 0), `up` a
    /// hint not parallel to it (the view's up is its part orthogonal to
    /// `forward`), for a `width × height` image with the given near
    /// distance (> 0). Same conventions as the camera's view: reversed Z
    /// with the far plane at infinity, `depth = near / distance along
    /// forward`, screen origin top-left, y down.
    pub fn from_frustum(
        eye: DVec3,
        forward: DVec3,
        up: DVec3,
        extent: Extent,
        width: u32,
        height: u32,
        near: f64,
    ) -> Result<View> {
        if !(eye.is_finite() && forward.is_finite() && up.is_finite()) {
            return Err(Error::param("view", "eye, forward and up must be finite"));
        }
        let forward = forward.normalize_or_zero();
        let right = forward.cross(up).normalize_or_zero();
        if forward == DVec3::ZERO || right == DVec3::ZERO {
            return Err(Error::param(
                "view",
                "forward is zero, or up is parallel to it",
            ));
        }
        View::resolve(eye, forward, right, extent, width, height, near)
    }

    /// The view from unit `forward` and `right` vectors (the camera's own
    /// path: its bits must not change).
    fn resolve(
        eye: DVec3,
        forward: DVec3,
        right: DVec3,
        extent: Extent,
        width: u32,
        height: u32,
        near: f64,
    ) -> Result<View> {
        if !(near > 0.0 && near.is_finite()) {
            return Err(Error::param("near", format!("{near} must be positive")));
        }
        if width == 0 || height == 0 {
            return Err(Error::param(
                "width/height",
                format!("{width}×{height} has no pixels"),
            ));
        }
        let up = right.cross(forward);
        let aspect = width as f64 / height as f64;
        let (tan_half_fov, window, symmetric) = match extent {
            Extent::FovY { degrees } => {
                if !(degrees > 0.0 && degrees < 180.0) {
                    return Err(Error::param(
                        "fov_y",
                        format!("{degrees} degrees is outside (0, 180)"),
                    ));
                }
                let t = (0.5 * degrees.to_radians()).tan();
                let window = Window {
                    left: -t * aspect,
                    right: t * aspect,
                    bottom: -t,
                    top: t,
                };
                (t, window, true)
            }
            Extent::Window {
                left,
                right,
                bottom,
                top,
            } => {
                let w = Window {
                    left: left / near,
                    right: right / near,
                    bottom: bottom / near,
                    top: top / near,
                };
                let finite = [w.left, w.right, w.bottom, w.top]
                    .iter()
                    .all(|v| v.is_finite());
                if !(finite && w.left < w.right && w.bottom < w.top) {
                    return Err(Error::param(
                        "window",
                        format!(
                            "[{left}, {right}] × [{bottom}, {top}] at near {near} is not a \
                             finite rectangle with left < right and bottom < top"
                        ),
                    ));
                }
                let t = w
                    .bottom
                    .abs()
                    .max(w.top.abs())
                    .max(w.left.abs().max(w.right.abs()) / aspect);
                (t, w, false)
            }
        };
        let view = DMat4::from_cols(
            DVec4::new(right.x, up.x, -forward.x, 0.0),
            DVec4::new(right.y, up.y, -forward.y, 0.0),
            DVec4::new(right.z, up.z, -forward.z, 0.0),
            DVec4::new(-right.dot(eye), -up.dot(eye), forward.dot(eye), 1.0),
        );
        // Reversed Z with an infinite far plane: z_clip = near * w_in,
        // w_clip = -z_view, so depth = near / distance along forward and
        // points at infinity (w_in = 0) land on depth 0.
        let projection = if symmetric {
            DMat4::from_cols(
                DVec4::new(1.0 / (tan_half_fov * aspect), 0.0, 0.0, 0.0),
                DVec4::new(0.0, 1.0 / tan_half_fov, 0.0, 0.0),
                DVec4::new(0.0, 0.0, 0.0, -1.0),
                DVec4::new(0.0, 0.0, near, 0.0),
            )
        } else {
            // x_ndc = (2 x / d - (r + l)) / (r - l) with d = -z_view: the
            // window's edges land on ±1 (glFrustum in tangent units).
            let (sx, sy) = (window.right - window.left, window.top - window.bottom);
            DMat4::from_cols(
                DVec4::new(2.0 / sx, 0.0, 0.0, 0.0),
                DVec4::new(0.0, 2.0 / sy, 0.0, 0.0),
                DVec4::new(
                    (window.right + window.left) / sx,
                    (window.top + window.bottom) / sy,
                    0.0,
                    -1.0,
                ),
                DVec4::new(0.0, 0.0, near, 0.0),
            )
        };
        let view_projection = projection * view;
        if !view_projection.is_finite() {
            return Err(Error::param(
                "view",
                "the frustum's projection is not finite",
            ));
        }
        Ok(View {
            eye,
            forward,
            right,
            up,
            tan_half_fov,
            window,
            symmetric,
            width,
            height,
            near,
            view_projection,
        })
    }

    /// Unit direction of the primary ray through pixel `(i, j)`'s centre,
    /// exactly as the contract defines it.
    #[inline]
    pub fn primary_ray(&self, i: u32, j: u32) -> DVec3 {
        self.primary_ray_unnormalized(i, j).normalize()
    }

    /// The same ray's direction before normalisation (for hit points,
    /// which do not depend on its length): `forward + x right + y up`
    /// with `(x, y)` the texel centre on the window at unit distance.
    #[inline]
    pub fn primary_ray_unnormalized(&self, i: u32, j: u32) -> DVec3 {
        let (w, h) = (self.width as f64, self.height as f64);
        let (x, y) = if self.symmetric {
            (
                (2.0 * (i as f64 + 0.5) / w - 1.0) * self.tan_half_fov * w / h,
                (1.0 - 2.0 * (j as f64 + 0.5) / h) * self.tan_half_fov,
            )
        } else {
            let win = &self.window;
            (
                win.left + (win.right - win.left) * ((i as f64 + 0.5) / w),
                win.top - (win.top - win.bottom) * ((j as f64 + 0.5) / h),
            )
        };
        self.forward + x * self.right + y * self.up
    }

    /// Where a world point in front of the eye (distance along `forward` >
    /// 0) lands on the image, in pixels (origin top-left, y down; texel
    /// `(i, j)` has its centre at `(i + 0.5, j + 0.5)`); `None` for points
    /// on or behind the eye's plane. Computed in f64 from the frustum, so
    /// it agrees with [`View::primary_ray_unnormalized`] up to rounding.
    pub fn pixel_of(&self, p: DVec3) -> Option<DVec2> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if !(z > 0.0) {
            return None;
        }
        let (x, y) = (d.dot(self.right) / z, d.dot(self.up) / z);
        let win = &self.window;
        Some(DVec2::new(
            (x - win.left) / (win.right - win.left) * self.width as f64,
            (win.top - y) / (win.top - win.bottom) * self.height as f64,
        ))
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
