//! Built-in shapes, exactly as the contract's "Built-in shapes" convention
//! defines them, in object space (the loader applies the transform).
//!
//! Every vertex carries a normal and a uv, and every triangle is
//! counter-clockwise seen from outside (the +Y side for the quad).

use crate::geom::Mesh;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A UV sphere of radius `r` with its pole axis on +Y.
///
/// Vertex `(k, m)` sits at `theta = pi k / rings`, `phi = 2 pi m / segments`,
/// position `r (sin theta cos phi, cos theta, -sin theta sin phi)`, uv
/// `(phi / 2pi, 1 - theta / pi)`, radial normal. The grid keeps a seam
/// column `m = segments` and one pole vertex per segment so that uvs are
/// continuous; the mesh is therefore not welded at the seam and the poles
/// (weld by position where adjacency matters).
/// Triangles: one per segment in each polar ring, two per quad elsewhere,
/// `2 segments (rings - 1)` in all. The caller checks `segments >= 3` and
/// `rings >= 2`.
pub fn sphere(r: f32, segments: u32, rings: u32, material: u32) -> Mesh {
    let cols = segments + 1;
    let mut mesh = Mesh::default();
    let n = (rings as usize + 1) * cols as usize;
    let (mut normals, mut uvs) = (vec![Vec3::ZERO; n], vec![Vec2::ZERO; n]);
    mesh.positions = vec![Vec3::ZERO; n];
    // Ring by ring in parallel (millions of vertices at fine
    // tessellations); each vertex is a function of (k, m) alone.
    // Each column's (sin, cos) of phi once, not once per ring: the same
    // values (the same call on the same argument), a ring's worth of
    // `sin_cos` instead of a sphere's.
    let columns: Vec<(f64, f64, f64)> = (0..cols)
        .map(|m| {
            let phi = 2.0 * PI * f64::from(m) / f64::from(segments);
            // The seam column (phi = 2 pi) repeats column 0 exactly, so the
            // mesh has no crack there (sin(2 pi) in floating point is not 0).
            let (sin_p, cos_p) = if m == segments {
                (0.0, 1.0)
            } else {
                phi.sin_cos()
            };
            (phi, sin_p, cos_p)
        })
        .collect();
    let rows = (mesh.positions.par_chunks_mut(cols as usize))
        .zip(normals.par_chunks_mut(cols as usize))
        .zip(uvs.par_chunks_mut(cols as usize));
    rows.enumerate()
        .for_each(|(k, ((positions, normals), uvs))| {
            let k = k as u32;
            let theta = PI * f64::from(k) / f64::from(rings);
            // The poles are exact: sin(pi) in floating point is not 0.
            let (sin_t, cos_t) = match k {
                0 => (0.0, 1.0),
                _ if k == rings => (0.0, -1.0),
                _ => theta.sin_cos(),
            };
            for (i, &(phi, sin_p, cos_p)) in columns.iter().enumerate() {
                let dir = DVec3::new(sin_t * cos_p, cos_t, -sin_t * sin_p);
                positions[i] = (f64::from(r) * dir).as_vec3();
                normals[i] = dir.normalize().as_vec3();
                uvs[i] = Vec2::new((phi / (2.0 * PI)) as f32, (1.0 - theta / PI) as f32);
            }
        });
    let v = |k: u32, m: u32| k * cols + m;
    mesh.triangles
        .reserve_exact(sphere_triangle_count(segments, rings) as usize);
    for k in 0..rings {
        for m in 0..segments {
            // Along +theta then +phi is counter-clockwise seen from outside:
            // d/dtheta × d/dphi points outward for this parametrisation.
            let (a, b, c, d) = (v(k, m), v(k + 1, m), v(k + 1, m + 1), v(k, m + 1));
            if k != rings - 1 {
                mesh.triangles.push([a, b, c]);
            }
            if k != 0 {
                mesh.triangles.push([a, c, d]);
            }
        }
    }
    mesh.normals = Some(normals);
    mesh.uvs = Some(uvs);
    mesh.material_ids = vec![material; mesh.triangles.len()];
    mesh
}

/// The number of triangles [`sphere`] makes: one per segment in each polar
/// ring, two per quad elsewhere.
pub fn sphere_triangle_count(segments: u32, rings: u32) -> u64 {
    2 * u64::from(segments) * u64::from(rings.saturating_sub(1))
}

/// One axis-aligned face: outward normal `n`, in-face "up" axis `t`, and
/// the box half-extents. The in-face "right" axis `s = t × n` makes
/// `s × t = n`, so corners in uv order (0,0), (1,0), (1,1), (0,1) run
/// counter-clockwise seen from outside, and uv spans [0, 1]².
fn push_face(mesh: &mut Mesh, n: Vec3, t: Vec3, half: Vec3, material: u32) {
    let s = t.cross(n);
    let base = mesh.positions.len() as u32;
    let normals = mesh.normals.get_or_insert_with(Vec::new);
    let uvs = mesh.uvs.get_or_insert_with(Vec::new);
    for uv in [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ] {
        let corner = n + (2.0 * uv.x - 1.0) * s + (2.0 * uv.y - 1.0) * t;
        mesh.positions.push(corner * half);
        normals.push(n);
        uvs.push(uv);
    }
    mesh.triangles.push([base, base + 1, base + 2]);
    mesh.triangles.push([base, base + 2, base + 3]);
    mesh.material_ids.extend([material; 2]);
}

/// A box of `size` centred on the origin: 24 vertices (flat face normals),
/// 12 triangles, each face's uv spanning [0, 1]².
pub fn cuboid(size: Vec3, material: u32) -> Mesh {
    let mut mesh = Mesh::default();
    let faces = [
        (Vec3::X, Vec3::Y),
        (Vec3::NEG_X, Vec3::Y),
        (Vec3::Z, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y),
        (Vec3::Y, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::Z),
    ];
    for (n, t) in faces {
        push_face(&mut mesh, n, t, size * 0.5, material);
    }
    mesh
}

/// A quad of `sx × sz` in the plane y = 0, centred, front face +Y: corners
/// `(±sx/2, 0, ±sz/2)`, uv `(x / sx + 1/2, 1/2 - z / sz)`. It is the +Y face
/// of a box of zero height.
pub fn quad(sx: f32, sz: f32, material: u32) -> Mesh {
    let mut mesh = Mesh::default();
    push_face(
        &mut mesh,
        Vec3::Y,
        Vec3::NEG_Z,
        Vec3::new(sx, 0.0, sz) * 0.5,
        material,
    );
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The loader's memory estimate counts what `sphere` generates.
    #[test]
    fn sphere_triangle_count_is_exact() {
        for (segments, rings) in [(3, 2), (4, 3), (7, 5), (20, 20), (64, 2)] {
            let mesh = sphere(1.0, segments, rings, 0);
            assert_eq!(
                sphere_triangle_count(segments, rings),
                mesh.triangles.len() as u64,
                "{segments} × {rings}"
            );
        }
    }
}
