//! Homogeneous clipping against the near plane, the far plane at infinity
//! and a guard band.
//!
//! The guard band keeps projected coordinates inside the fixed-point range
//! of triangle setup while letting most triangles through unclipped; the
//! viewport itself is enforced by the scissor (bounding boxes clamped to the
//! screen), not by clipping.

use super::vertex::ClipVertex;
use glam::Vec4;

/// Maximum vertices of a triangle clipped by 6 planes.
pub const MAX_CLIPPED_VERTICES: usize = 9;

/// A convex polygon produced by clipping one triangle.
#[derive(Debug, Clone, Copy)]
pub struct ClippedPolygon<const N: usize> {
    /// Vertices, the first `len` are valid, in the input winding order.
    pub vertices: [ClipVertex<N>; MAX_CLIPPED_VERTICES],
    /// Number of valid vertices (0 when the triangle is rejected).
    pub len: usize,
}

/// The clip planes as `dot(plane, position) >= 0` half-spaces, for a guard
/// band of `guard_x`, `guard_y` (in NDC units, >= 1).
#[inline]
fn planes(guard_x: f32, guard_y: f32) -> [Vec4; 6] {
    [
        Vec4::new(0.0, 0.0, -1.0, 1.0),     // near: z <= w (depth <= 1)
        Vec4::new(0.0, 0.0, 1.0, 0.0),      // far at infinity: z >= 0
        Vec4::new(1.0, 0.0, 0.0, guard_x),  // x >= -g w
        Vec4::new(-1.0, 0.0, 0.0, guard_x), // x <= g w
        Vec4::new(0.0, 1.0, 0.0, guard_y),  // y >= -g w
        Vec4::new(0.0, -1.0, 0.0, guard_y), // y <= g w
    ]
}

/// Plane distance, written out so that no fused multiply-add can change it.
#[inline]
fn distance(plane: Vec4, p: Vec4) -> f32 {
    plane.x * p.x + plane.y * p.y + plane.z * p.z + plane.w * p.w
}

/// Outcodes of a vertex: bit i set when outside plane i.
#[inline]
fn outcode(planes: &[Vec4; 6], p: Vec4) -> u8 {
    let mut code = 0;
    for (i, plane) in planes.iter().enumerate() {
        // `!(d >= 0)` also flags NaN positions as outside, so a NaN vertex
        // can never reach setup.
        if !(distance(*plane, p) >= 0.0) {
            code |= 1 << i;
        }
    }
    code
}

/// The point where the edge from `inside` to `outside` crosses the plane.
///
/// Always interpolated from the inside vertex, whichever order the edge has
/// in the polygon, so that two triangles sharing an edge (or the same
/// triangle with reversed winding) get bit-identical clipped vertices.
#[inline]
fn intersect<const N: usize>(
    plane: Vec4,
    inside: &ClipVertex<N>,
    outside: &ClipVertex<N>,
) -> ClipVertex<N> {
    let d_in = distance(plane, inside.position);
    let d_out = distance(plane, outside.position);
    let t = d_in / (d_in - d_out);
    let lerp = |a: f32, b: f32| a + t * (b - a);
    let (a, b) = (inside.position, outside.position);
    let mut varyings = inside.varyings;
    for (v, o) in varyings.iter_mut().zip(outside.varyings.iter()) {
        *v = lerp(*v, *o);
    }
    ClipVertex {
        position: Vec4::new(
            lerp(a.x, b.x),
            lerp(a.y, b.y),
            lerp(a.z, b.z),
            lerp(a.w, b.w),
        ),
        varyings,
    }
}

/// The clip planes' bits of [`vertex_code`] (the outcodes
/// [`clip_triangle`] clips by).
pub(crate) const CLIP_PLANES: u16 = 0x3f;

/// A vertex's outcode against the clip planes (bits 0-5), plus bits 6-9
/// for lying in front of the eye (`w > 0`) and beyond one side of the
/// screen (`x < -w`, `x > w`, `y < -w`, `y > w`). Those compares are
/// exact, and a triangle whose three vertices lie beyond the same side
/// projects wholly beyond it: it covers no pixel centre (the nearest
/// lies half a pixel inside the border) and needs no setup.
#[inline]
pub(crate) fn vertex_code(p: Vec4, guard_x: f32, guard_y: f32) -> u16 {
    let planes = planes(guard_x, guard_y);
    let mut code = outcode(&planes, p) as u16;
    if p.w > 0.0 {
        code |= u16::from(p.x < -p.w) << 6
            | u16::from(p.x > p.w) << 7
            | u16::from(p.y < -p.w) << 8
            | u16::from(p.y > p.w) << 9;
    }
    code
}

/// Clips a triangle. Returns `len == 0` when nothing is left, `len == 3`
/// with the input untouched when no clipping was needed.
pub fn clip_triangle<const N: usize>(
    triangle: [ClipVertex<N>; 3],
    guard_x: f32,
    guard_y: f32,
) -> ClippedPolygon<N> {
    let planes = planes(guard_x, guard_y);
    let codes = triangle.map(|v| outcode(&planes, v.position));
    let mut out = ClippedPolygon {
        vertices: [triangle[0]; MAX_CLIPPED_VERTICES],
        len: 0,
    };
    if codes[0] & codes[1] & codes[2] != 0 {
        return out; // all outside one plane
    }
    if triangle.iter().any(|v| !v.position.is_finite()) {
        return out; // a NaN or infinite vertex has no position to clip
    }
    out.vertices[..3].copy_from_slice(&triangle);
    out.len = 3;
    if codes[0] | codes[1] | codes[2] == 0 {
        return out; // all inside: the common case
    }
    let mut scratch = out.vertices;
    for (i, &plane) in planes.iter().enumerate() {
        if (codes[0] | codes[1] | codes[2]) & (1 << i) == 0 {
            continue;
        }
        let mut n = 0;
        for k in 0..out.len {
            let cur = out.vertices[k];
            let next = out.vertices[(k + 1) % out.len];
            let cur_in = distance(plane, cur.position) >= 0.0;
            let next_in = distance(plane, next.position) >= 0.0;
            if cur_in {
                scratch[n] = cur;
                n += 1;
            }
            if cur_in != next_in {
                scratch[n] = if cur_in {
                    intersect(plane, &cur, &next)
                } else {
                    intersect(plane, &next, &cur)
                };
                n += 1;
            }
        }
        out.vertices[..n].copy_from_slice(&scratch[..n]);
        out.len = n;
        if n < 3 {
            out.len = 0;
            return out;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f32, y: f32, z: f32, w: f32) -> ClipVertex<1> {
        ClipVertex {
            position: Vec4::new(x, y, z, w),
            varyings: [w],
        }
    }

    fn inside(p: Vec4, g: f32) -> bool {
        let eps = 1e-5 * p.w.abs().max(1.0);
        p.z <= p.w + eps && p.z >= -eps && p.x.abs() <= g * p.w + eps && p.y.abs() <= g * p.w + eps
    }

    #[test]
    fn unclipped_triangle_passes_untouched() {
        let t = [
            v(0.0, 0.0, 0.5, 1.0),
            v(0.5, 0.0, 0.5, 1.0),
            v(0.0, 0.5, 0.5, 1.0),
        ];
        let c = clip_triangle(t, 2.0, 2.0);
        assert_eq!(c.len, 3);
        assert_eq!(&c.vertices[..3], &t);
    }

    #[test]
    fn vertices_at_infinity_are_kept_on_the_far_plane() {
        // z = 0, w > 0: a point at infinity in front of the camera.
        let t = [
            v(0.0, 0.0, 0.0, 1.0),
            v(0.5, 0.0, 0.0, 1.0),
            v(0.0, 0.5, 0.0, 2.0),
        ];
        let c = clip_triangle(t, 2.0, 2.0);
        assert_eq!(c.len, 3);
    }

    #[test]
    fn w_zero_vertex_is_clipped_by_the_guard_band_into_finite_vertices() {
        // An extruded vertex at infinity sideways (w = 0, x != 0): its
        // projection is unbounded, the guard band must cut it.
        let t = [
            v(0.0, 0.0, 0.5, 1.0),
            v(0.5, 0.0, 0.5, 1.0),
            v(1.0, 0.0, 0.0, 0.0),
        ];
        let c = clip_triangle(t, 2.0, 2.0);
        assert!(c.len >= 3);
        for p in &c.vertices[..c.len] {
            assert!(
                p.position.w > 0.0,
                "w must be positive after clipping: {p:?}"
            );
            assert!(inside(p.position, 2.0), "{p:?}");
        }
    }

    #[test]
    fn triangle_crossing_the_near_plane_is_cut_there() {
        // Third vertex behind the eye (w < 0).
        let t = [
            v(0.0, 0.0, 0.1, 1.0),
            v(0.5, 0.0, 0.1, 1.0),
            v(0.0, 0.0, 0.1, -1.0),
        ];
        let c = clip_triangle(t, 4.0, 4.0);
        assert_eq!(c.len, 4);
        for p in &c.vertices[..c.len] {
            assert!(inside(p.position, 4.0), "{p:?}");
            // varyings interpolate along with the position
            assert!((p.varyings[0] - p.position.w).abs() < 1e-6);
        }
        // The new vertices lie on the near plane z = w.
        let on_near = c.vertices[..c.len]
            .iter()
            .filter(|p| (p.position.z - p.position.w).abs() < 1e-6)
            .count();
        assert_eq!(on_near, 2);
    }

    #[test]
    fn triangle_fully_behind_is_rejected() {
        let t = [
            v(0.0, 0.0, 0.1, -1.0),
            v(0.5, 0.0, 0.1, -1.0),
            v(0.0, 0.5, 0.1, -2.0),
        ];
        assert_eq!(clip_triangle(t, 2.0, 2.0).len, 0);
    }

    #[test]
    fn nan_vertex_is_rejected_or_cut_away() {
        let t = [
            v(f32::NAN, 0.0, 0.5, 1.0),
            v(0.5, 0.0, 0.5, 1.0),
            v(0.0, 0.5, 0.5, 1.0),
        ];
        let c = clip_triangle(t, 2.0, 2.0);
        for p in &c.vertices[..c.len] {
            assert!(p.position.is_finite());
        }
    }

    #[test]
    fn clipping_is_independent_of_winding() {
        let a = v(0.0, 0.0, 0.1, 1.0);
        let b = v(0.5, 0.2, 0.1, 1.0);
        let c = v(0.1, 0.3, 0.1, -1.0);
        let p = clip_triangle([a, b, c], 4.0, 4.0);
        let q = clip_triangle([a, c, b], 4.0, 4.0);
        let mut ps: Vec<[u32; 4]> = p.vertices[..p.len]
            .iter()
            .map(|v| v.position.to_array().map(f32::to_bits))
            .collect();
        let mut qs: Vec<[u32; 4]> = q.vertices[..q.len]
            .iter()
            .map(|v| v.position.to_array().map(f32::to_bits))
            .collect();
        ps.sort();
        qs.sort();
        assert_eq!(ps, qs);
    }
}
