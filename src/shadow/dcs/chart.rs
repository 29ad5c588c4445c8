//! The light as a 2-D chart seen from one receiver: where light samples
//! and projected silhouette edges meet.
//!
//! - **Rect lights**: the light's own coordinates `(s, t)`,
//!   `x = c + s u + t v`, the square `[−1, 1]²`; edges are projected from
//!   `p` onto the light's plane ([`RectProjection`]).
//! - **Sphere lights**: gnomonic coordinates around the axis `p → c`
//!   (straight edges stay straight), scaled by `1 / tan θmax` so that the
//!   cone the sphere subtends is the unit disc; edges are clipped to the
//!   half-space in front of `p` and to the plane of the visible rim (parts
//!   beyond it are inside the light).
//!
//! In both charts the light's centre is the origin, and a sample `s` is
//! occluded by an edge's change of depth complexity exactly when the
//! segment from the origin to `s` crosses the projected edge.

use crate::shadow::kit::light_frame::{clip_to_square, RectFrame, RectProjection};
use crate::shadow::kit::wedge_geometry::LightBound;
use glam::DVec3;

/// One receiver's view of one light.
#[derive(Debug, Clone, Copy)]
pub enum ReceiverChart {
    /// A rect light's own coordinates.
    Rect {
        /// The light.
        frame: RectFrame,
        /// The projection from the receiver (`None`: in the light's
        /// plane, where no edge projects).
        projection: Option<RectProjection>,
    },
    /// Scaled gnomonic coordinates of a sphere light.
    Sphere {
        /// The receiver.
        p: DVec3,
        /// Unit axis `p → c`.
        axis: DVec3,
        /// Chart x direction.
        e1: DVec3,
        /// Chart y direction.
        e2: DVec3,
        /// `tan θmax`.
        tan: f64,
        /// `W` of the rim plane.
        w_max: f64,
    },
}

impl ReceiverChart {
    /// The chart of `light` from `p`; `None` when `p` sees no light (inside
    /// a sphere light, or not finite).
    pub fn new(light: &LightBound, p: DVec3) -> Option<ReceiverChart> {
        if !p.is_finite() {
            return None;
        }
        match *light {
            LightBound::Rect(frame) => Some(ReceiverChart::Rect {
                frame,
                projection: RectProjection::new(&frame, p),
            }),
            LightBound::Sphere { center, radius } => {
                let rel = center - p;
                let d = rel.length();
                if !(d > radius) || !d.is_finite() {
                    return None;
                }
                let axis = rel / d;
                let e1 = axis.any_orthonormal_vector();
                let e2 = axis.cross(e1);
                let sin = radius / d;
                let cos = (1.0 - sin * sin).max(0.0).sqrt();
                if !(cos > 0.0) {
                    return None;
                }
                let tan = sin / cos;
                Some(ReceiverChart::Sphere {
                    p,
                    axis,
                    e1,
                    e2,
                    tan,
                    w_max: d * cos * cos * tan,
                })
            }
        }
    }

    /// Chart coordinates of the light point `x`.
    #[inline]
    pub fn point(&self, x: DVec3) -> [f64; 2] {
        match self {
            ReceiverChart::Rect { frame, .. } => frame.chart(x),
            ReceiverChart::Sphere {
                p,
                axis,
                e1,
                e2,
                tan,
                ..
            } => {
                let v = x - *p;
                let w = v.dot(*axis) * tan;
                [v.dot(*e1) / w, v.dot(*e2) / w]
            }
        }
    }

    /// The light point at chart coordinates `xy` (the inverse of
    /// [`point`](Self::point)): on a rect light's plane, or, for a sphere
    /// light whose centre is `centre`, on the plane through the centre
    /// across the axis.
    pub fn light_point(&self, xy: [f64; 2], centre: DVec3) -> DVec3 {
        match self {
            ReceiverChart::Rect { frame, .. } => frame.center + frame.u * xy[0] + frame.v * xy[1],
            ReceiverChart::Sphere {
                p,
                axis,
                e1,
                e2,
                tan,
                ..
            } => {
                let d = (centre - *p).dot(*axis);
                *p + (*axis + (*e1 * xy[0] + *e2 * xy[1]) * *tan) * d
            }
        }
    }

    /// The rect light's projection from the receiver, when the chart is
    /// one and the receiver is off the light's plane.
    #[inline]
    pub fn rect_projection(&self) -> Option<&RectProjection> {
        match self {
            ReceiverChart::Rect { projection, .. } => projection.as_ref(),
            ReceiverChart::Sphere { .. } => None,
        }
    }

    /// The edge `v0 → v1` projected from the receiver into the chart,
    /// clipped to the part that can occlude the light (in front of the
    /// receiver, not beyond the light) and to the chart's square.
    #[inline]
    pub fn edge(&self, v0: DVec3, v1: DVec3) -> Option<([f64; 2], [f64; 2])> {
        match self {
            ReceiverChart::Rect { projection, .. } => projection.as_ref()?.edge(v0, v1),
            ReceiverChart::Sphere {
                p,
                axis,
                e1,
                e2,
                tan,
                w_max,
            } => {
                let h = |q: DVec3| {
                    let v = q - *p;
                    [v.dot(*e1), v.dot(*e2), v.dot(*axis) * tan]
                };
                clip_to_square(h(v0), h(v1), *w_max)
            }
        }
    }
}
