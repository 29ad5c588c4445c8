//! Hard shadow volumes as a building block: construction of the volume
//! of every opaque caster from a point (closed casters: caps and
//! silhouette quads; open and non-manifold ones: Bergeron's
//! generalisation), silhouette quads, and exact `i32` stencil counts.
//! Shadow volumes, the wedge techniques and DCS all start from these.

use crate::error::Result;
use crate::geom::silhouette::faces_point;
use crate::geom::EdgeAdjacency;
use crate::raster::{
    draw, draw_depth_shift_counts, ClipVertex, CompareFunc, CullMode, Framebuffer, NoFragmentStage,
    RasterState, StencilFace, StencilOp, StencilState,
};
use crate::scene::{LightShape, Scene};
use crate::view::View;
use glam::Vec3;
use rayon::prelude::*;
use std::borrow::Cow;

/// A shadow volume ready to draw: finite welded vertices first, the same
/// vertices at infinity (`v − L`, w = 0) after them.
#[derive(Debug, Clone, Default)]
pub struct ShadowVolume {
    /// Clip-space vertices.
    pub vertices: Vec<ClipVertex<0>>,
    /// Triangles, oriented so that their outward normals leave the volume.
    pub triangles: Vec<[u32; 3]>,
    /// Proven: no volume reaches the eye or the visible part of the near
    /// plane. Then z-pass gives exactly the z-fail counts (see
    /// [`near_region_outside`]), and [`stencil_counts`] counts with it.
    pub eye_outside: bool,
}

/// The point a light's hard shadows are cast from: its centre.
pub fn light_point(shape: &LightShape) -> Vec3 {
    match *shape {
        LightShape::Rect { center, .. } | LightShape::Sphere { center, .. } => center,
    }
}

/// Opaque shadow casters: the faces hard shadow volumes are built from.
/// When every triangle is one (the usual scene), this is the scene's own
/// adjacency, borrowed; otherwise it is rebuilt over the casters only.
pub fn caster_adjacency<'a>(
    scene: &Scene,
    geometry: &'a crate::geom::SceneGeometry,
) -> Cow<'a, EdgeAdjacency> {
    let casts = |f: u32| {
        let object = &scene.objects[geometry.triangle_object[f as usize] as usize];
        let material = &scene.materials[geometry.triangle_material[f as usize] as usize];
        object.cast_shadows && material.is_opaque()
    };
    if (0..geometry.triangles.len() as u32).all(casts) {
        Cow::Borrowed(geometry.adjacency())
    } else {
        Cow::Owned(EdgeAdjacency::build(geometry, casts))
    }
}

/// Whether a ball around the eye that holds the visible near rectangle
/// (with a wide margin) lies outside the shadow volume of every caster
/// face: a conservative proof, `false` when in doubt.
///
/// Why it matters: per pixel, z-fail counts `Σ s` over the volume faces
/// that fail the depth test and z-pass counts `-Σ s` over those that pass
/// (`s = +1` back-facing, `-1` front-facing), so the two differ by
/// `Σ s` over *all* faces covering the pixel. The volumes are closed
/// (caps included, open casters by Bergeron's rule) and rasterized
/// watertight, so that sum is the same at every pixel the clipped
/// volume's cut edges do not reach, and it is minus the number of volumes
/// containing the eye. With the eye and the visible near plane outside
/// every volume, no cut edge reaches the screen and the sum is 0: z-pass
/// gives the z-fail counts bit for bit, whatever the depth buffer holds.
///
/// A face's volume (the points behind it seen from the light) lies behind
/// its plane and inside the three planes through the light and its edges;
/// the ball is outside it when it is wholly on the light's side of the
/// face's plane, or wholly outside one of the edge planes. Closed casters
/// need only their light-facing faces (their volume is the union of
/// those faces' volumes); open ones need every face.
pub fn near_region_outside(adj: &EdgeAdjacency, lit: &[bool], view: &View, light: Vec3) -> bool {
    let l = light.as_dvec3();
    let e = view.eye;
    let aspect = view.width as f64 / view.height as f64;
    let t = view.tan_half_fov;
    // Eye to a near-plane corner, twice over, plus a margin far above the
    // f32 rounding of the rasterized volume (relative 1e-7).
    let corner = view.near * (1.0 + t * t * (1.0 + aspect * aspect)).sqrt();
    let rho = 2.0 * corner + 1e-5 * (e - l).length();
    if !rho.is_finite() {
        return false;
    }
    adj.face_vertices
        .par_iter()
        .with_min_len(BUILD_CHUNK)
        .zip(adj.face_closed.par_iter().zip(lit))
        .all(|(f, (&closed, &lit))| {
            if closed && !lit {
                return true;
            }
            let [a, b, c] = f.map(|i| adj.positions[i as usize].as_dvec3());
            let n = (b - a).cross(c - a);
            let (dl, de) = (n.dot(l - a), n.dot(e - a));
            let reach = rho * n.length();
            if (dl > 0.0 && de > reach) || (dl < 0.0 && de < -reach) {
                return true;
            }
            [(a, b, c), (b, c, a), (c, a, b)].iter().any(|&(p, q, o)| {
                let m = (p - l).cross(q - l);
                let side = m.dot(o - l);
                let d = m.dot(e - l);
                let reach = rho * m.length();
                (side > 0.0 && d < -reach) || (side < 0.0 && d > reach)
            })
        })
}

/// Faces or edges per parallel work item of [`build_volume`].
const BUILD_CHUNK: usize = 4096;

/// Builds the volume of every caster in `adj` for a point light at `light`.
/// Vertices, caps and sides are made in parallel pieces, concatenated in
/// order: the same volume for any thread count.
pub fn build_volume(adj: &EdgeAdjacency, view: &View, light: Vec3) -> ShadowVolume {
    let lit = faces_point(adj, light);
    let (eye_outside, (mut vertices, infinite)) = rayon::join(
        || near_region_outside(adj, &lit, view, light),
        || {
            rayon::join(
                || {
                    adj.positions
                        .par_iter()
                        .with_min_len(BUILD_CHUNK)
                        .map(|p| ClipVertex {
                            position: view.clip_point(*p),
                            varyings: [],
                        })
                        .collect::<Vec<_>>()
                },
                || {
                    adj.positions
                        .par_iter()
                        .with_min_len(BUILD_CHUNK)
                        .map(|p| ClipVertex {
                            position: view.clip_direction(*p - light),
                            varyings: [],
                        })
                        .collect::<Vec<_>>()
                },
            )
        },
    );
    vertices.extend(infinite);
    let n = adj.positions.len() as u32;
    let inf = |v: u32| v + n;
    let caps = adj
        .face_vertices
        .par_chunks(BUILD_CHUNK)
        .enumerate()
        .map(|(chunk, faces)| {
            let mut out = Vec::with_capacity(faces.len() * 2);
            for k in 0..faces.len() {
                let slot = chunk * BUILD_CHUNK + k;
                cap_triangles(adj, &lit, slot, n, &mut out);
            }
            out
        });
    let sides = adj
        .edges
        .par_chunks(BUILD_CHUNK)
        .enumerate()
        .map(|(chunk, edges)| {
            let mut out = Vec::new();
            let first = chunk * BUILD_CHUNK;
            for [a, b, m] in (first..first + edges.len()).filter_map(|e| side_quad(adj, &lit, e)) {
                let quad = [a, b, inf(b), inf(a)];
                for _ in 0..m {
                    out.push([quad[0], quad[1], quad[2]]);
                    out.push([quad[0], quad[2], quad[3]]);
                }
            }
            out
        });
    let pieces: Vec<Vec<[u32; 3]>> = caps.chain(sides).collect();
    let mut triangles = Vec::with_capacity(pieces.iter().map(Vec::len).sum());
    for piece in pieces {
        triangles.extend(piece);
    }
    ShadowVolume {
        vertices,
        triangles,
        eye_outside,
    }
}

/// The cap triangles of face `slot` of `adj` (welded vertex ids; the
/// same vertex at infinity is `id + n`): closed casters put light-facing
/// faces in the near cap and the others, at infinity, in the far cap;
/// open casters (Bergeron) put every face in both, oriented out of its own
/// layer.
pub fn cap_triangles(
    adj: &EdgeAdjacency,
    lit: &[bool],
    slot: usize,
    n: u32,
    out: &mut Vec<[u32; 3]>,
) {
    let [a, b, c] = adj.face_vertices[slot];
    let inf = |v: u32| v + n;
    match (adj.face_closed[slot], lit[slot]) {
        (true, true) => out.push([a, b, c]),
        (true, false) => out.push([inf(a), inf(b), inf(c)]),
        (false, true) => {
            out.push([a, b, c]);
            out.push([inf(a), inf(c), inf(b)]);
        }
        (false, false) => {
            out.push([a, c, b]);
            out.push([inf(a), inf(b), inf(c)]);
        }
    }
}

/// The side quad of one edge, if its multiplicity `m = Σ s·d` is not zero:
/// its welded vertices `[a, b]` ordered so that the quad
/// `[a, b, b at infinity, a at infinity]` faces out of the volume, and
/// `|m|`, the copies to draw. `lit[f]`: face `f` faces the light point.
/// `e` indexes `adj.edges`.
pub fn side_quad(adj: &EdgeAdjacency, lit: &[bool], e: usize) -> Option<[u32; 3]> {
    let m: i32 = adj
        .uses(e)
        .iter()
        .map(|u| {
            let s = u.slot as usize;
            let weight = match (adj.face_closed[s], lit[s]) {
                (true, true) => 1,
                (true, false) => 0,
                (false, true) => 1,
                (false, false) => -1,
            };
            weight * u.direction as i32
        })
        .sum();
    let [lo, hi] = adj.edges[e].v;
    match m.signum() {
        1 => Some([hi, lo, m as u32]),
        -1 => Some([lo, hi, m.unsigned_abs()]),
        _ => None,
    }
}

/// Every side quad of a volume ([`side_quad`]), in edge order: penumbra
/// wedges reuse exactly these quads.
pub fn silhouette_quads(adj: &EdgeAdjacency, lit: &[bool]) -> Vec<[u32; 3]> {
    (0..adj.edges.len())
        .filter_map(|e| side_quad(adj, lit, e))
        .collect()
}

/// Raster state counting a volume in the stencil.
pub fn stencil_state(zpass: bool) -> RasterState {
    let (front, back) = if zpass {
        (
            StencilFace {
                pass: StencilOp::Increment,
                ..StencilFace::KEEP
            },
            StencilFace {
                pass: StencilOp::Decrement,
                ..StencilFace::KEEP
            },
        )
    } else {
        (
            StencilFace {
                depth_fail: StencilOp::Decrement,
                ..StencilFace::KEEP
            },
            StencilFace {
                depth_fail: StencilOp::Increment,
                ..StencilFace::KEEP
            },
        )
    };
    RasterState {
        // Closer wins in reversed Z; a volume face exactly at the surface
        // (a near cap copying a scene triangle, bit-identical depth) fails
        // and counts as behind, so lit faces do not shadow themselves.
        depth_func: CompareFunc::Greater,
        depth_write: false,
        stencil: Some(StencilState {
            front,
            back,
            reference: 0,
        }),
        cull: CullMode::None,
    }
}

/// Per-pixel stencil counts of one light's volume over the scene depth.
///
/// Z-fail unless `zpass`; when the volume proves the eye outside every
/// volume ([`ShadowVolume::eye_outside`]), the z-fail counts are computed
/// by z-pass, which gives the same bits and lets the rasterizer skip the
/// volume parts hidden behind the scene (most of them).
pub fn stencil_counts(
    framebuffer: &mut Framebuffer,
    volume: &ShadowVolume,
    zpass: bool,
) -> Result<Vec<i32>> {
    stencil_counts_of(
        framebuffer,
        &volume.vertices,
        &volume.triangles,
        zpass || volume.eye_outside,
    )
}

/// Per pixel, for each of `scales`, from one setup of the volume
/// ([`draw_depth_shift_counts`]): `None`, its [`stencil_counts`];
/// `Some(scale)`, how much that count changes when the framebuffer's
/// stored depth `d` is replaced by `d × scale` (the f32 product, as a
/// depth-scaled copy would hold: that copy's counts minus the
/// framebuffer's, exactly), tested only where a face comes between the
/// two depths.
pub fn stencil_count_shifts(
    framebuffer: &mut Framebuffer,
    volume: &ShadowVolume,
    zpass: bool,
    scales: &[Option<f32>],
) -> Result<Vec<Vec<i32>>> {
    draw_depth_shift_counts(
        framebuffer,
        &stencil_state(zpass || volume.eye_outside),
        &volume.vertices,
        &volume.triangles,
        scales,
    )
}

/// Per-pixel stencil counts of part of a volume (`triangles` over the
/// volume's `vertices`): a closed sub-volume (one connected caster's caps
/// and sides) counts exactly like a whole one.
pub fn stencil_counts_of(
    framebuffer: &mut Framebuffer,
    vertices: &[ClipVertex<0>],
    triangles: &[[u32; 3]],
    zpass: bool,
) -> Result<Vec<i32>> {
    framebuffer.clear_stencil(0);
    let grid = framebuffer.grid();
    let mut none = vec![(); grid.tile_count()];
    let _stats = draw(
        framebuffer,
        &mut none,
        &stencil_state(zpass),
        vertices,
        triangles,
        &NoFragmentStage,
    )?;
    if std::env::var_os("PENUMBRA_DEBUG_STATS").is_some() {
        eprintln!("{_stats:?}");
    }
    Ok(framebuffer.stencil_image())
}
