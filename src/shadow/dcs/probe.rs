//! The cost choice's probe: what counting and rays would meet in this
//! scene, measured on a fixed sample of receivers and edges before either
//! path is built.
//!
//! Triangles, receivers and samples alone do not tell the two paths'
//! costs apart: the subdivided bunny's counting costs about five times
//! the spheres' per triangle (97 (receiver, edge) pairs per penumbra
//! receiver against about 20), and its rays half as much (three quarters
//! of its receivers are lit, and a lit receiver's rays are answered by
//! one walk). So the plan reads two figures from this probe:
//!
//! - **pairs**: per receiver, the edges whose wedge holds it, the work of
//!   the counter pass;
//! - **penumbra receivers**: those with at least one such edge, the ones
//!   whose rays take full walks.
//!
//! An edge `(a, b)` changes a receiver `p`'s count somewhere on the light
//! exactly when it is a silhouette from a light point `x` on a line from
//! `p` through the edge. For such `x`, `x = p + s(e − p)` with `s > 1` and
//! `e` on the edge, so each face plane has `x` and `p` on opposite sides:
//! the edge is a silhouette from `x` if and only if it is one from `p`.
//! The test is therefore: a silhouette from `p`, and the edge's projection
//! from `p` onto the light's plane meets the light.
//!
//! Deterministic: the receivers are a stride over the pixels, the edges
//! those of one triangle per block at a hashed place, both fixed by the
//! counts, and the sums are integers, so the plan is the same for any
//! thread count and SIMD level.

use crate::gbuffer::GBuffer;
use crate::geom::SceneGeometry;
use crate::scene::{Light, LightShape, Scene};
use crate::shadow::kit::light_frame::{RectFrame, RectProjection};
use glam::Vec3;
use rayon::prelude::*;

/// Receivers sampled (at most; every surface pixel when there are fewer).
const RECEIVERS: usize = 256;
/// Edges sampled: at most this many...
const EDGES: usize = 1 << 16;
/// ... and at most one per this many triangles (a small scene's counting
/// is cheap, and so must its probe be), but at least [`MIN_EDGES`].
const TRIANGLES_PER_EDGE: usize = 4;
/// The least edges sampled.
const MIN_EDGES: usize = 4096;
/// Triangles per task of the scan for the drawn edges' other faces.
const SCAN_CHUNK: usize = 1 << 14;

/// What the probe found, scaled to the whole frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ProbeEstimate {
    /// Estimated (receiver, edge) pairs over every receiver.
    pub pairs: f64,
    /// Estimated receivers with at least one such edge.
    pub penumbra: f64,
    /// Receivers sampled.
    pub receivers_sampled: usize,
    /// Edges sampled (of the light's candidates).
    pub edges_sampled: usize,
}

impl ProbeEstimate {
    /// What `--explain` says of it.
    pub fn describe(&self) -> String {
        format!(
            "probe of {} receivers and {} edges: about {:.0} (receiver, edge) pairs, {:.0} \
             penumbra receivers",
            self.receivers_sampled, self.edges_sampled, self.pairs, self.penumbra
        )
    }
}

/// One sampled edge: its two faces' planes `n · x = d` as `[n, d]` (a
/// non-manifold edge, a silhouette from everywhere, gets [`EVERYWHERE`])
/// and its ends. The planes come first: every receiver reads them, and
/// only the few edges that are silhouettes from it read the ends.
struct ProbeEdge {
    planes: [[f32; 4]; 2],
    a: Vec3,
    b: Vec3,
}

/// Planes that make an edge a silhouette from every point: in front of
/// the first (`0 > −1`) and not of the second (`0 > 1`).
const EVERYWHERE: [[f32; 4]; 2] = [[0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 1.0]];

/// The light's projection from receiver `p` (the counting path's own,
/// [`RectProjection`]): a rect light as it is, a sphere light as the
/// square around its disc facing `p`. `None` when `p` does not see the
/// light's emitting side (no rays are traced and no edge counted there).
fn projection(light: &Light, p: Vec3) -> Option<RectProjection> {
    let frame = match light.shape {
        LightShape::Rect {
            center,
            u,
            v,
            two_sided,
        } => {
            if !two_sided && u.cross(v).dot(p - center) <= 0.0 {
                return None;
            }
            RectFrame::new(center.as_dvec3(), u.as_dvec3(), v.as_dvec3())
        }
        LightShape::Sphere { center, radius } => {
            let [s, t] = orthonormal((center - p).normalize_or_zero());
            RectFrame::new(
                center.as_dvec3(),
                (s * radius).as_dvec3(),
                (t * radius).as_dvec3(),
            )
        }
    };
    RectProjection::new(&frame, p.as_dvec3())
}

/// Whether the edge `a b`, projected from the receiver onto the light's
/// plane (clipped to the slab between them), meets the light.
fn meets(projection: &RectProjection, a: Vec3, b: Vec3) -> bool {
    projection.edge(a.as_dvec3(), b.as_dvec3()).is_some()
}

/// Two unit vectors completing `n` to an orthonormal frame.
fn orthonormal(n: Vec3) -> [Vec3; 2] {
    let helper = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let s = n.cross(helper).normalize_or_zero();
    [s, n.cross(s)]
}

/// The drawn triangle's place in its block of `stride` triangles: a
/// hashed offset, not a plain stride, which would alias with the strips
/// meshes are made of (an even stride over a strip of quads draws the
/// same one of each quad's two triangles, and so the same kinds of edges:
/// the diagonals, say, silhouettes almost nowhere).
fn sample_offset(block: usize, stride: usize) -> usize {
    let mut x = (block as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((x ^ (x >> 31)) % stride as u64) as usize
}

/// Whether the edge is a silhouette from `p`: `p` strictly in front of one
/// face and not of the other.
fn silhouette_from(edge: &ProbeEdge, p: Vec3) -> bool {
    let front = |[x, y, z, d]: [f32; 4]| x * p.x + y * p.y + z * p.z > d;
    front(edge.planes[0]) != front(edge.planes[1])
}

/// A sample of the casters' edges, about one in `stride`, without the
/// welded adjacency (which rays, if chosen, never use: at 4M triangles it
/// costs 0.8 s). One triangle in `stride` is drawn (at a hashed place in
/// each block of `stride`), and with it each edge it runs from its lesser
/// vertex index to the greater: a manifold edge is drawn exactly when
/// that face is. One pass over every caster then finds the drawn edges'
/// other faces, those running the same two vertices the other way; a bit
/// filter over the drawn edges' hashes (sixteen bits an edge, small
/// enough for the second-level cache) turns away nearly every caster edge
/// before the sorted list is searched. An edge whose other
/// face is not found (a boundary, or faces meeting at copies of a vertex
/// split for their normals or texture coordinates, as along a sphere's
/// seam) is dropped, and the returned weight (edges per kept edge) makes
/// up for it. Edges whose faces both see the light's bounding sphere from
/// the same side (silhouettes from no light point) are dropped too: they
/// meet no receiver.
fn sampled_edges(
    geometry: &SceneGeometry,
    casts: &(dyn Fn(usize) -> bool + Sync),
    light: &Light,
    stride: usize,
) -> (Vec<ProbeEdge>, f64) {
    let triangles = &geometry.triangles;
    // (lesser vertex, greater vertex, face), sorted: the drawn edges.
    let mut drawn: Vec<(u32, u32, usize)> = (0..triangles.len().div_ceil(stride))
        .into_par_iter()
        .with_min_len(1024)
        .flat_map_iter(|block| {
            let t = block * stride + sample_offset(block, stride);
            let face = (t < triangles.len() && casts(t)).then_some(t);
            face.into_iter().flat_map(move |t| {
                let v = triangles[t];
                (0..3).filter_map(move |k| {
                    let (a, b) = (v[k], v[(k + 1) % 3]);
                    (a < b).then_some((a, b, t))
                })
            })
        })
        .collect();
    // The entries are distinct (a face draws each edge once), so the
    // parallel sort's order is the one order.
    drawn.par_sort_unstable();
    let bits = (drawn.len() * 16).next_power_of_two();
    let bit = |a: u32, b: u32| {
        let h =
            (u64::from(a.min(b)) << 32 | u64::from(a.max(b))).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        (h >> 40) as usize & (bits - 1)
    };
    let mut filter = vec![0u64; bits.div_ceil(64)];
    for &(a, b, _) in &drawn {
        filter[bit(a, b) / 64] |= 1 << (bit(a, b) % 64);
    }
    // Every caster's edges running a drawn edge backwards: its other
    // faces, in triangle order (the same list for any thread count).
    let mut others: Vec<(usize, usize)> = triangles
        .par_chunks(SCAN_CHUNK)
        .enumerate()
        .flat_map_iter(|(chunk, faces)| {
            let mut found = Vec::new();
            for (k, v) in faces.iter().enumerate() {
                for e in 0..3 {
                    let (a, b) = (v[e], v[(e + 1) % 3]);
                    // Only edges running from the greater vertex can be a
                    // drawn edge backwards: half of them, before hashing.
                    if a <= b {
                        continue;
                    }
                    let h = bit(a, b);
                    if filter[h / 64] & 1 << (h % 64) == 0 {
                        continue;
                    }
                    let t = chunk * SCAN_CHUNK + k;
                    let i = drawn.partition_point(|&(x, y, _)| (x, y) < (b, a));
                    if drawn.get(i).is_some_and(|d| (d.0, d.1) == (b, a)) && casts(t) {
                        found.push((i, t));
                    }
                }
            }
            found
        })
        .collect();
    // Distinct pairs: the one order, as above.
    others.par_sort_unstable();
    let (centre, radius) = match light.shape {
        LightShape::Rect { center, u, v, .. } => (center, (u + v).length().max((u - v).length())),
        LightShape::Sphere { center, radius } => (center, radius),
    };
    let position = |v: u32| geometry.positions[v as usize];
    let plane = |t: usize| {
        let n = geometry.unit_normals[t];
        [n.x, n.y, n.z, n.dot(position(triangles[t][0]))]
    };
    // One face on the other side: manifold. More (non-manifold): a
    // silhouette from everywhere. None: on a closed object, faces meeting
    // at copies of the edge's vertices (a sphere's seam), so dropped, and
    // the others weigh for them; on an open one, most likely its
    // boundary, a silhouette from everywhere, as the counting path has it
    // (an interior's walls: dropping them had the probe find a fifth of
    // `dabrovic.toml`'s pairs).
    let open = |t: usize| {
        let object = geometry.triangle_object.get(t).copied().unwrap_or(0) as usize;
        !geometry.object_closed.get(object).copied().unwrap_or(true)
    };
    // Each drawn edge's other faces, its run of `others` (sorted by drawn
    // index), in one merge; the edges are then built in parallel.
    let mut runs = Vec::with_capacity(drawn.len());
    let (mut next, mut unmatched) = (0, 0usize);
    for (i, &(_, _, t)) in drawn.iter().enumerate() {
        let start = next;
        while next < others.len() && others[next].0 == i {
            next += 1;
        }
        unmatched += usize::from(start == next && !open(t));
        runs.push(start..next);
    }
    let run = |i: usize| {
        runs.get(i)
            .and_then(|r| others.get(r.clone()))
            .unwrap_or(&[])
    };
    let edges: Vec<ProbeEdge> = drawn
        .par_iter()
        .enumerate()
        .filter_map(|(i, &(a, b, t))| {
            let planes = match run(i) {
                [] if open(t) => EVERYWHERE,
                [] => return None,
                [(_, u)] => [plane(t), plane(*u)],
                _ => EVERYWHERE,
            };
            let [s0, s1] = planes.map(|[x, y, z, d]| Vec3::new(x, y, z).dot(centre) - d);
            if s0.abs() > radius && s1.abs() > radius && (s0 > 0.0) == (s1 > 0.0) {
                return None;
            }
            Some(ProbeEdge {
                planes,
                a: position(a),
                b: position(b),
            })
        })
        .collect();
    let weight = stride as f64 * drawn.len() as f64 / (drawn.len() - unmatched).max(1) as f64;
    (edges, weight)
}

/// Probes `light` over the casting triangles of `scene` at the surface
/// receivers of `gbuffer`'s whole frame (`surfaces` of them).
pub fn probe(
    scene: &Scene,
    geometry: &SceneGeometry,
    light: &Light,
    gbuffer: &GBuffer,
    surfaces: usize,
) -> ProbeEstimate {
    if surfaces == 0 || geometry.triangles.is_empty() {
        return ProbeEstimate::default();
    }
    // The casters of the counting path (`caster_adjacency`'s rule).
    let object_casts: Vec<bool> = scene.objects.iter().map(|o| o.cast_shadows).collect();
    let opaque: Vec<bool> = scene.materials.iter().map(|m| m.is_opaque()).collect();
    let casts = |t: usize| {
        object_casts[geometry.triangle_object[t] as usize]
            && opaque[geometry.triangle_material[t] as usize]
    };
    // Three edges a triangle, each drawn with its ascending face.
    let triangles = geometry.triangles.len();
    let sampled = (triangles / TRIANGLES_PER_EDGE).clamp(MIN_EDGES, EDGES);
    let edge_stride = (triangles * 3 / 2).div_ceil(sampled);
    let (edges, edge_weight) = sampled_edges(geometry, &casts, light, edge_stride);
    // The whole frame's receivers, also in a band of it (the band must
    // make the frame's choice).
    let pixel_stride = surfaces.div_ceil(RECEIVERS);
    let receivers: Vec<Vec3> = gbuffer.frame_surfaces().step_by(pixel_stride).collect();
    let per_receiver: Vec<u64> = receivers
        .par_iter()
        .map(|&p| {
            let Some(projection) = projection(light, p) else {
                return 0;
            };
            edges
                .iter()
                .filter(|e| silhouette_from(e, p) && meets(&projection, e.a, e.b))
                .count() as u64
        })
        .collect();
    let scale = surfaces as f64 / receivers.len() as f64;
    ProbeEstimate {
        pairs: per_receiver.iter().sum::<u64>() as f64 * edge_weight * scale,
        penumbra: per_receiver.iter().filter(|&&c| c > 0).count() as f64 * scale,
        receivers_sampled: receivers.len(),
        edges_sampled: edges.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `projection` and `meets` against a brute force: points along the
    /// edge, each projected from `p` through onto the light's plane,
    /// tested against the rectangle. Random edges around and above random receivers;
    /// cases within a small margin of the rectangle's border are skipped
    /// (the brute force's spacing cannot settle them).
    #[test]
    fn the_projection_test_agrees_with_points_along_the_edge() {
        let light = Light {
            shape: LightShape::Rect {
                center: Vec3::new(0.2, 4.0, -0.1),
                u: Vec3::new(0.7, 0.0, 0.0),
                v: Vec3::new(0.0, 0.0, 0.5),
                two_sided: false,
            },
            radiance: Vec3::ONE,
            texture: None,
        };
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut met, mut missed) = (0, 0);
        for _ in 0..4000 {
            let p = Vec3::new(next() * 4.0 - 2.0, next() * 0.5, next() * 4.0 - 2.0);
            // Between p and the light, and sometimes below p or above
            // the light's plane.
            let towards = p + (Vec3::new(0.2, 4.0, -0.1) - p) * (next() * 1.4 - 0.2);
            let a = towards + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 1.5;
            let b = a + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 2.0;
            let centre = Vec3::new(0.2, 4.0, -0.1);
            let (up, axes, half) = (Vec3::Y, [Vec3::X, Vec3::Z], [0.7, 0.5]);
            let height = up.dot(centre - p);
            // Distance of the edge's points' projections from the
            // rectangle (negative inside), over 4000 points.
            let mut nearest = f32::INFINITY;
            for k in 0..=4000 {
                let x = a + (b - a) * (k as f32 / 4000.0);
                let h = up.dot(x - p);
                if h <= 0.0 || h > height {
                    continue;
                }
                let q = p + (x - p) * (height / h) - centre;
                let s = axes[0].dot(q).abs() - half[0];
                let t = axes[1].dot(q).abs() - half[1];
                nearest = nearest.min(s.max(t));
            }
            if nearest.abs() < 0.02 {
                continue;
            }
            let inside = nearest < 0.0;
            let projection = projection(&light, p).expect("below the light");
            assert_eq!(meets(&projection, a, b), inside, "p {p} a {a} b {b}");
            if inside {
                met += 1;
            } else {
                missed += 1;
            }
        }
        assert!(met > 200 && missed > 200, "{met} met, {missed} missed");
    }
}
