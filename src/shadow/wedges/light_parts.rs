//! The light split into four quarters, each with its occluded fraction and
//! a rectangle bounding the occluded region: what a wedge adds to a
//! receiver (thesis §3.3, blending) and how parts combine. Shared by the
//! wedge pass (which accumulates them per tile) and wedge blending.

use crate::shadow::kit::light_frame::{projected_edge, EdgeRegion, Polygon, RectFrame};
use crate::shadow::kit::wedge_geometry::HalfWedge;
use glam::DVec3;

/// The four quarters of the light square, split at the centre.
pub const QUARTERS: [[f64; 4]; 4] = [
    [0.0, 0.0, 1.0, 1.0],
    [-1.0, 0.0, 0.0, 1.0],
    [-1.0, -1.0, 0.0, 0.0],
    [0.0, -1.0, 1.0, 0.0],
];

/// An empty rectangle.
pub(super) const EMPTY: [f32; 4] = [
    f32::INFINITY,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NEG_INFINITY,
];

/// One quarter of the light as seen from one receiver: the occluded
/// fraction of the quarter and a rectangle bounding the occluded region
/// (light-square coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightPart {
    /// Occluded fraction of the quarter.
    pub occ: f32,
    /// `[s0, t0, s1, t1]`, empty when `s0 > s1`.
    pub rect: [f32; 4],
}

impl Default for LightPart {
    fn default() -> Self {
        LightPart {
            occ: 0.0,
            rect: EMPTY,
        }
    }
}

fn area(r: [f32; 4]) -> f32 {
    if r[0] < r[2] && r[1] < r[3] {
        (r[2] - r[0]) * (r[3] - r[1])
    } else {
        0.0
    }
}

fn union(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

fn intersection(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    [
        a[0].max(b[0]),
        a[1].max(b[1]),
        a[2].min(b[2]),
        a[3].min(b[3]),
    ]
}

pub(super) fn to_f32(b: [f64; 4]) -> [f32; 4] {
    b.map(|v| v as f32)
}

/// Adds one half-wedge's edge, seen from `p`, to a receiver's SV-buffer:
/// per quarter, `±m` times the area of the edge's region there, and the
/// rectangle grown (outer) or cut (inner).
pub fn accumulate(
    parts: &mut [LightPart; 4],
    frame: &RectFrame,
    p: DVec3,
    half: &HalfWedge,
    c_side: f64,
) {
    let Some((a, b)) = projected_edge(frame, p, half.q0, half.q1) else {
        return;
    };
    let region = EdgeRegion::new(a, b, c_side);
    // The region over the whole light once; each quarter cuts it with
    // two axis half-planes.
    let whole = region.polygon(Polygon::square());
    let Some(reach) = whole.bbox() else {
        return;
    };
    let m = half.weight as f64;
    for (part, quarter) in parts.iter_mut().zip(QUARTERS) {
        if reach[0] >= quarter[2]
            || reach[2] <= quarter[0]
            || reach[1] >= quarter[3]
            || reach[3] <= quarter[1]
        {
            continue;
        }
        let poly = whole
            .clip(|x| if quarter[0] < 0.0 { -x[0] } else { x[0] })
            .clip(|x| if quarter[1] < 0.0 { -x[1] } else { x[1] });
        let covered = poly.area();
        if !(covered > 0.0) {
            continue;
        }
        if half.outer {
            part.occ += (m * covered) as f32;
            if let Some(b) = poly.bbox() {
                part.rect = union(part.rect, to_f32(b));
            }
        } else {
            part.occ -= (m * covered) as f32;
            part.rect = match region.complement_bbox(Polygon::rect(quarter)) {
                Some(b) => intersection(part.rect, to_f32(b)),
                None => EMPTY,
            };
        }
    }
}

/// Blends one silhouette's part `s` into the V-buffer's part `v` with the
/// effective overlapped area heuristic (thesis eq. 3.1).
pub fn blend_part(v: &mut LightPart, s: &LightPart) {
    let a_s = s.occ.clamp(0.0, 1.0);
    let b_s = area(s.rect);
    if a_s == 0.0 && b_s == 0.0 {
        return;
    }
    let a_v = v.occ.clamp(0.0, 1.0);
    let b_v = area(v.rect);
    let mut occ = a_s + a_v;
    let beta = area(intersection(s.rect, v.rect));
    if beta > 0.0 && b_s > 0.0 && b_v > 0.0 {
        occ -= (a_v / b_v).min(1.0) * (a_s / b_s).min(1.0) * beta;
    }
    v.occ = occ.clamp(0.0, 1.0);
    v.rect = union(v.rect, s.rect);
}
