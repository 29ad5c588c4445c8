//! Properties of the raster pipeline: watertight coverage with the top-left
//! rule, clipping of vertices at infinity and across the near plane, and
//! depth/stencil operation tables, all through the public draw call.

use crate::common;

use common::Rng;
use glam::Vec4;
use penumbra::internal::raster::{
    draw, ClipVertex, CompareFunc, CullMode, FragmentBatch, FragmentStage, Framebuffer,
    RasterState, StencilFace, StencilOp, StencilState, TileGrid, TiledTarget,
};

/// Counts how often each pixel is shaded.
struct CountStage;

impl FragmentStage<0> for CountStage {
    type Target = Box<[u32]>;
    fn shade(&self, batch: &FragmentBatch<0>, target: &mut Box<[u32]>) {
        for k in batch.lanes() {
            target[batch.local + k] += 1;
        }
    }
}

/// Screen position (pixels, y down) to a clip-space vertex with w = 1.
fn screen_vertex(x: f64, y: f64, w: u32, h: u32) -> ClipVertex<0> {
    ClipVertex {
        position: Vec4::new(
            (2.0 * x / w as f64 - 1.0) as f32,
            (1.0 - 2.0 * y / h as f64) as f32,
            0.5,
            1.0,
        ),
        varyings: [],
    }
}

fn coverage_counts(
    w: u32,
    h: u32,
    verts: &[ClipVertex<0>],
    tris: &[[u32; 3]],
    state: RasterState,
) -> Vec<u32> {
    let grid = TileGrid::new(w, h).unwrap();
    let mut fb = Framebuffer::new(grid);
    let mut counts = TiledTarget::new(grid, 0u32);
    draw(
        &mut fb,
        counts.tiles_mut(),
        &state,
        verts,
        tris,
        &CountStage,
    )
    .unwrap();
    counts.to_image()
}

const NO_DEPTH: RasterState = RasterState {
    depth_func: CompareFunc::Always,
    depth_write: false,
    stencil: None,
    cull: CullMode::None,
};

/// Twice the signed area of (a, b, p) in exact integer half-pixel units.
fn orient(a: (i64, i64), b: (i64, i64), p: (i64, i64)) -> i64 {
    (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
}

/// Random grid meshes of a rectangle: interior vertices jittered to
/// half-pixel positions (so many pixel centres lie exactly on edges),
/// random diagonal directions, random winding and starting vertex. Every
/// pixel centre strictly inside the rectangle must be covered exactly
/// once, every one outside never.
#[test]
fn watertight_random_grid_meshes() {
    let (w, h) = (157u32, 131u32); // not tile multiples: exercises edge tiles
    let mut rng = Rng(0x5eed);
    for round in 0..40 {
        let cells = rng.range(2, 12) as usize;
        let (x0, y0) = (rng.range(-40, 30) * 2, rng.range(-40, 30) * 2); // half-pixel units
        let (x1, y1) = (x0 + rng.range(60, 300) * 2, y0 + rng.range(60, 300) * 2);
        // grid of vertices in half-pixel units
        let mut pts = vec![(0i64, 0i64); (cells + 1) * (cells + 1)];
        'retry: loop {
            for j in 0..=cells {
                for i in 0..=cells {
                    let bx = x0 + (x1 - x0) * i as i64 / cells as i64;
                    let by = y0 + (y1 - y0) * j as i64 / cells as i64;
                    let cw = (x1 - x0) / cells as i64 / 3;
                    let ch = (y1 - y0) / cells as i64 / 3;
                    let jx = if i == 0 || i == cells {
                        0
                    } else {
                        rng.range(-cw, cw)
                    };
                    let jy = if j == 0 || j == cells {
                        0
                    } else {
                        rng.range(-ch, ch)
                    };
                    pts[j * (cells + 1) + i] = (bx + jx, by + jy);
                }
            }
            let mut tris = Vec::new();
            for j in 0..cells {
                for i in 0..cells {
                    let a = (j * (cells + 1) + i) as u32;
                    let (b, c, d) = (a + 1, a + cells as u32 + 2, a + cells as u32 + 1);
                    let pair = if rng.next_u64() & 1 == 0 {
                        [[a, b, c], [a, c, d]]
                    } else {
                        [[a, b, d], [b, c, d]]
                    };
                    for t in pair {
                        let p = t.map(|k| pts[k as usize]);
                        if orient(p[0], p[1], p[2]) <= 0 {
                            continue 'retry; // a fold: draw new jitter
                        }
                        let mut t = if rng.next_u64() & 1 == 0 {
                            t
                        } else {
                            [t[0], t[2], t[1]]
                        };
                        t.rotate_left(rng.range(0, 2) as usize);
                        tris.push(t);
                    }
                }
            }
            let verts: Vec<_> = pts
                .iter()
                .map(|&(x, y)| screen_vertex(x as f64 / 2.0, y as f64 / 2.0, w, h))
                .collect();
            let counts = coverage_counts(w, h, &verts, &tris, NO_DEPTH);
            for py in 0..h {
                for px in 0..w {
                    let (cx, cy) = (2 * px as i64 + 1, 2 * py as i64 + 1);
                    let n = counts[(py * w + px) as usize];
                    let strictly_inside = cx > x0 && cx < x1 && cy > y0 && cy < y1;
                    let outside = cx < x0 || cx > x1 || cy < y0 || cy > y1;
                    if strictly_inside {
                        assert_eq!(n, 1, "round {round}: pixel ({px},{py}) covered {n} times");
                    } else if outside {
                        assert_eq!(n, 0, "round {round}: pixel ({px},{py}) outside covered");
                    } else {
                        assert!(n <= 1, "round {round}: boundary pixel covered twice");
                    }
                }
            }
            break;
        }
    }
}

/// Fans around a centre on a pixel centre, spokes through pixel centres:
/// the centre and every spoke are shared by many triangles, yet each
/// pixel is covered at most once and interior pixels exactly once.
#[test]
fn watertight_fans_sharing_a_vertex() {
    let (w, h) = (96u32, 96u32);
    let mut rng = Rng(7);
    for _ in 0..30 {
        let c = (2 * rng.range(30, 60) + 1, 2 * rng.range(30, 60) + 1);
        let n = rng.range(3, 24) as usize;
        // Boundary vertices on a circle, sorted by angle, at half-pixels.
        let r = rng.range(20, 120) as f64;
        let mut ring: Vec<(i64, i64)> = (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * (k as f64 + 0.3 * rng.f64()) / n as f64;
                (
                    c.0 + (r * a.cos()).round() as i64,
                    c.1 + (r * a.sin()).round() as i64,
                )
            })
            .collect();
        ring.dedup();
        let mut pts = vec![c];
        pts.extend(&ring);
        let m = ring.len();
        let mut tris = Vec::new();
        let mut ok = true;
        for k in 0..m {
            let t = [0u32, 1 + k as u32, 1 + ((k + 1) % m) as u32];
            let p = t.map(|i| pts[i as usize]);
            if orient(p[0], p[1], p[2]) <= 0 {
                ok = false;
            }
            tris.push(if rng.next_u64() & 1 == 0 {
                t
            } else {
                [t[0], t[2], t[1]]
            });
        }
        if !ok {
            continue;
        }
        let verts: Vec<_> = pts
            .iter()
            .map(|&(x, y)| screen_vertex(x as f64 / 2.0, y as f64 / 2.0, w, h))
            .collect();
        let counts = coverage_counts(w, h, &verts, &tris, NO_DEPTH);
        for py in 0..h {
            for px in 0..w {
                let p = (2 * px as i64 + 1, 2 * py as i64 + 1);
                let cnt = counts[(py * w + px) as usize];
                assert!(cnt <= 1, "pixel ({px},{py}) covered {cnt} times");
                // Strictly inside the ring polygon (convex ring test per
                // boundary edge, fan is star-shaped around c).
                let inside_all = (0..m).all(|k| {
                    let a = ring[k];
                    let b = ring[(k + 1) % m];
                    orient(a, b, p) > 0
                });
                // Only conclusive for a convex ring; skip otherwise.
                let convex =
                    (0..m).all(|k| orient(ring[k], ring[(k + 1) % m], ring[(k + 2) % m]) > 0);
                if convex && inside_all {
                    assert_eq!(cnt, 1, "interior pixel ({px},{py}) not covered");
                }
            }
        }
    }
}

/// Samples exactly on a horizontal top edge belong to the triangle below;
/// on a left edge to the triangle to the right.
#[test]
fn top_left_rule_assigns_edge_samples() {
    let (w, h) = (16u32, 16u32);
    // Square [2.5, 10.5]^2 split along its diagonal: pixel centres on all
    // four sides.
    let v = [
        screen_vertex(2.5, 2.5, w, h),
        screen_vertex(10.5, 2.5, w, h),
        screen_vertex(10.5, 10.5, w, h),
        screen_vertex(2.5, 10.5, w, h),
    ];
    let counts = coverage_counts(w, h, &v, &[[0, 1, 2], [0, 2, 3]], NO_DEPTH);
    let at = |x: u32, y: u32| counts[(y * w + x) as usize];
    assert_eq!(at(5, 2), 1, "top edge sample is in");
    assert_eq!(at(5, 10), 0, "bottom edge sample is out");
    assert_eq!(at(2, 5), 1, "left edge sample is in");
    assert_eq!(at(10, 5), 0, "right edge sample is out");
    let total: u32 = counts.iter().sum();
    assert_eq!(total, 8 * 8);
}

/// The projection used by these tests: reversed Z, infinite far plane.
fn project(p: glam::DVec4, near: f64) -> ClipVertex<0> {
    // camera at origin looking down -z, fov 90°, aspect 1
    ClipVertex {
        position: Vec4::new(p.x as f32, p.y as f32, (near * p.w) as f32, (-p.z) as f32),
        varyings: [],
    }
}

/// Exact (f64) camera-ray test for a triangle that may have a vertex at
/// infinity (w = 0: a direction) or cross the near plane.
fn ray_hits(pixel: (u32, u32), size: u32, tri: [glam::DVec4; 3], near: f64) -> Option<f64> {
    use glam::DVec3;
    let x = (2.0 * (pixel.0 as f64 + 0.5) / size as f64) - 1.0;
    let y = 1.0 - 2.0 * (pixel.1 as f64 + 0.5) / size as f64;
    let d = DVec3::new(x, y, -1.0);
    // Triangle (a, b, c) with c possibly a direction: points a + s (b - a) + t (c - a)
    // (finite c) or a + s (b - a) + t c (direction c), s, t >= 0 and s + t <= 1
    // for finite c, s in [0, 1]... solved generally as a barycentric/linear system.
    let a = tri[0].truncate() / tri[0].w;
    let b = tri[1].truncate() / tri[1].w;
    let (e2, finite) = if tri[2].w == 0.0 {
        (tri[2].truncate(), false)
    } else {
        (tri[2].truncate() / tri[2].w - a, true)
    };
    let e1 = b - a;
    // Solve a + u e1 + v e2 = t d.
    let m = glam::DMat3::from_cols(e1, e2, -d);
    if m.determinant().abs() < 1e-300 {
        return None;
    }
    let sol = m.inverse() * (-a);
    let (u, v, t) = (sol.x, sol.y, sol.z);
    let inside = if finite {
        u >= 0.0 && v >= 0.0 && u + v <= 1.0
    } else {
        // infinite wedge: a + u (b - a) + v c, with u in [0,1], v >= 0
        (0.0..=1.0).contains(&u) && v >= 0.0
    };
    let z = -t; // view-space z of the hit
    (inside && -z >= near).then_some(t)
}

fn check_against_rays(tri: [glam::DVec4; 3], near: f64) {
    let size = 64u32;
    let verts: Vec<_> = tri.iter().map(|&p| project(p, near)).collect();
    let counts = coverage_counts(size, size, &verts, &[[0, 1, 2]], NO_DEPTH);
    let mut mismatches = 0;
    let mut covered = 0;
    for py in 0..size {
        for px in 0..size {
            let got = counts[(py * size + px) as usize] == 1;
            let want = ray_hits((px, py), size, tri, near).is_some();
            covered += got as u32;
            if got != want {
                mismatches += 1;
            }
        }
    }
    assert!(covered > 0, "triangle not drawn at all");
    // Mismatches only from vertex snapping (1/256 px): at most a handful of
    // pixel centres lying within that distance of an edge.
    assert!(
        mismatches <= 2,
        "{mismatches} pixels disagree with exact rays"
    );
}

#[test]
fn vertex_at_infinity_projects_to_its_vanishing_direction() {
    use glam::DVec4;
    // Two finite vertices and one direction (w = 0) going away from the
    // camera and sideways: the extruded side of a shadow volume.
    check_against_rays(
        [
            DVec4::new(-0.5, -0.4, -2.0, 1.0),
            DVec4::new(0.3, -0.5, -2.0, 1.0),
            DVec4::new(0.2, 0.3, -1.0, 0.0),
        ],
        0.1,
    );
    // Direction perpendicular to the view axis: only the guard band keeps
    // it finite.
    check_against_rays(
        [
            DVec4::new(-0.5, -0.4, -2.0, 1.0),
            DVec4::new(0.3, -0.5, -2.0, 1.0),
            DVec4::new(1.0, 0.2, 0.0, 0.0),
        ],
        0.1,
    );
}

#[test]
fn triangle_crossing_the_near_plane_is_cut_exactly() {
    use glam::DVec4;
    check_against_rays(
        [
            DVec4::new(-0.5, -0.3, -2.0, 1.0),
            DVec4::new(0.6, -0.4, -2.0, 1.0),
            DVec4::new(0.1, 0.5, 1.0, 1.0), // behind the camera
        ],
        0.2,
    );
}

/// Two full-screen quads: the first at depth 0.5 writes depth; the second
/// at depth `d2` is tested with each compare function. The survivors and
/// the stored depth must follow the table.
#[test]
fn depth_function_table() {
    let (w, h) = (24u32, 20u32);
    let quad = |depth: f32| -> Vec<ClipVertex<0>> {
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|&(x, y)| ClipVertex {
                position: Vec4::new(x, y, depth, 1.0),
                varyings: [],
            })
            .collect()
    };
    let tris = [[0u32, 1, 2], [0, 2, 3]];
    let funcs = [
        CompareFunc::Never,
        CompareFunc::Less,
        CompareFunc::LessEqual,
        CompareFunc::Equal,
        CompareFunc::GreaterEqual,
        CompareFunc::Greater,
        CompareFunc::NotEqual,
        CompareFunc::Always,
    ];
    for func in funcs {
        for d2 in [0.25f32, 0.5, 0.75] {
            for write in [false, true] {
                let grid = TileGrid::new(w, h).unwrap();
                let mut fb = Framebuffer::new(grid);
                let mut counts = TiledTarget::new(grid, 0u32);
                let first = RasterState {
                    depth_func: CompareFunc::Always,
                    depth_write: true,
                    ..RasterState::default()
                };
                draw(
                    &mut fb,
                    counts.tiles_mut(),
                    &first,
                    &quad(0.5),
                    &tris,
                    &CountStage,
                )
                .unwrap();
                let second = RasterState {
                    depth_func: func,
                    depth_write: write,
                    ..RasterState::default()
                };
                draw(
                    &mut fb,
                    counts.tiles_mut(),
                    &second,
                    &quad(d2),
                    &tris,
                    &CountStage,
                )
                .unwrap();
                let pass = func.test(d2, 0.5);
                let want_count = 1 + pass as u32;
                let want_depth = if pass && write { d2 } else { 0.5 };
                for y in 0..h {
                    for x in 0..w {
                        assert_eq!(counts.get(x, y), want_count, "{func:?} {d2}");
                        assert_eq!(fb.depth(x, y), want_depth, "{func:?} {d2} write {write}");
                    }
                }
            }
        }
    }
}

/// Stencil: separate front/back operations on stencil-fail, depth-fail and
/// pass, with 32-bit counts that go past 255 and below 0 without wrapping.
#[test]
fn stencil_operation_table_and_wide_counts() {
    let (w, h) = (16u32, 16u32);
    let quad = |depth: f32, ccw: bool| -> (Vec<ClipVertex<0>>, Vec<[u32; 3]>) {
        let v = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|&(x, y)| ClipVertex {
                position: Vec4::new(x, y, depth, 1.0),
                varyings: [],
            })
            .collect();
        let t = if ccw {
            vec![[0, 1, 2], [0, 2, 3]]
        } else {
            vec![[0, 2, 1], [0, 3, 2]]
        };
        (v, t)
    };
    let grid = TileGrid::new(w, h).unwrap();
    let mut fb = Framebuffer::new(grid);
    let mut none: Vec<()> = vec![(); grid.tile_count()];
    // Scene depth 0.5.
    let (v, t) = quad(0.5, true);
    draw(
        &mut fb,
        &mut none,
        &RasterState::default(),
        &v,
        &t,
        &penumbra::internal::raster::NoFragmentStage,
    )
    .unwrap();
    fb.clear_stencil(0);
    // z-fail style: back faces increment on depth fail, front faces
    // decrement on depth fail.
    let zfail = StencilState {
        front: StencilFace {
            depth_fail: StencilOp::Decrement,
            ..StencilFace::KEEP
        },
        back: StencilFace {
            depth_fail: StencilOp::Increment,
            ..StencilFace::KEEP
        },
        reference: 0,
    };
    let state = RasterState {
        depth_func: CompareFunc::Greater,
        depth_write: false,
        stencil: Some(zfail),
        cull: CullMode::None,
    };
    // 300 back faces behind the scene (depth 0.25 < 0.5 fails "Greater").
    let (v, t) = quad(0.25, false);
    for _ in 0..300 {
        draw(
            &mut fb,
            &mut none,
            &state,
            &v,
            &t,
            &penumbra::internal::raster::NoFragmentStage,
        )
        .unwrap();
    }
    assert_eq!(fb.stencil(3, 3), 300, "no 8-bit wrap");
    // 310 front faces behind: 300 - 310 = -10, signed.
    let (v, t) = quad(0.25, true);
    for _ in 0..310 {
        draw(
            &mut fb,
            &mut none,
            &state,
            &v,
            &t,
            &penumbra::internal::raster::NoFragmentStage,
        )
        .unwrap();
    }
    assert_eq!(fb.stencil(3, 3), -10);
    // Faces in front of the scene (depth pass): unchanged under z-fail ops.
    let (v, t) = quad(0.75, false);
    draw(
        &mut fb,
        &mut none,
        &state,
        &v,
        &t,
        &penumbra::internal::raster::NoFragmentStage,
    )
    .unwrap();
    assert_eq!(fb.stencil(3, 3), -10);
    // Stencil-fail op: test `0 == stored` fails everywhere (stored -10), so
    // stencil_fail = Replace(7) applies; the depth buffer is untouched.
    let replace = StencilState {
        front: StencilFace {
            func: CompareFunc::Equal,
            stencil_fail: StencilOp::Replace,
            depth_fail: StencilOp::Zero,
            pass: StencilOp::Invert,
        },
        back: StencilFace::KEEP,
        reference: 7,
    };
    let st2 = RasterState {
        stencil: Some(replace),
        ..state
    };
    let (v, t) = quad(0.75, true);
    draw(
        &mut fb,
        &mut none,
        &st2,
        &v,
        &t,
        &penumbra::internal::raster::NoFragmentStage,
    )
    .unwrap();
    assert_eq!(fb.stencil(5, 9), 7);
    // Now stored == 7 == reference: passes; depth passes (0.75 > 0.5): Invert.
    draw(
        &mut fb,
        &mut none,
        &st2,
        &v,
        &t,
        &penumbra::internal::raster::NoFragmentStage,
    )
    .unwrap();
    assert_eq!(fb.stencil(5, 9), !7);
    assert_eq!(fb.depth(5, 9), 0.5, "depth writes were off");
}

/// Perspective-correct interpolation: a varying equal to view-space depth
/// must come out exact at every pixel of a slanted quad, which screen-space
/// linear interpolation would not give.
#[test]
fn perspective_correct_varyings() {
    struct Capture;
    impl FragmentStage<1> for Capture {
        type Target = Box<[f32]>;
        fn shade(&self, b: &FragmentBatch<1>, t: &mut Box<[f32]>) {
            let v = b.varyings[0].to_array();
            for k in b.lanes() {
                t[b.local + k] = v[k];
            }
        }
    }
    let near = 0.1f32;
    // A floor plane y = -1 from z = -1 to z = -20, camera at origin, fov 90.
    let pts = [(-3.0f32, -1.0), (3.0, -1.0), (3.0, -20.0), (-3.0, -20.0)];
    let verts: Vec<ClipVertex<1>> = pts
        .iter()
        .map(|&(x, z)| ClipVertex {
            position: Vec4::new(x, -1.0, near, -z),
            varyings: [-z],
        })
        .collect();
    let (w, h) = (64u32, 64u32);
    let grid = TileGrid::new(w, h).unwrap();
    let mut fb = Framebuffer::new(grid);
    let mut out = TiledTarget::new(grid, f32::NAN);
    draw(
        &mut fb,
        out.tiles_mut(),
        &RasterState::default(),
        &verts,
        &[[0, 1, 2], [0, 2, 3]],
        &Capture,
    )
    .unwrap();
    let mut checked = 0;
    for y in 0..h {
        for x in 0..w {
            let v = out.get(x, y);
            if v.is_nan() {
                continue;
            }
            // exact view depth of the floor at this pixel: ray y = -1
            let ny = 1.0 - 2.0 * (y as f64 + 0.5) / h as f64;
            let want = 1.0 / -ny; // y_view = ny * depth = -1
            assert!(
                (v as f64 - want).abs() < 1e-4 * want,
                "({x},{y}): {v} vs {want}"
            );
            // depth buffer holds near / w
            assert!((fb.depth(x, y) as f64 - near as f64 / want).abs() < 1e-6);
            checked += 1;
        }
    }
    assert!(checked > 500);
}

/// A clip-space vertex anywhere around the screen, at a random depth.
fn random_vertex(rng: &mut Rng) -> ClipVertex<0> {
    ClipVertex {
        position: Vec4::new(
            (rng.f64() * 3.0 - 1.5) as f32,
            (rng.f64() * 3.0 - 1.5) as f32,
            rng.f64() as f32,
            1.0,
        ),
        varyings: [],
    }
}

/// `n` independent random triangles.
/// A framebuffer over `grid` holding the depth of `scene` (default
/// state, no fragment stage): the receivers the stencil tests draw over.
fn scene_depth(grid: TileGrid, scene: &[ClipVertex<0>], tris: &[[u32; 3]]) -> Framebuffer {
    let mut fb = Framebuffer::new(grid);
    let mut none = vec![(); grid.tile_count()];
    let state = RasterState::default();
    draw(
        &mut fb,
        &mut none,
        &state,
        scene,
        tris,
        &penumbra::internal::raster::NoFragmentStage,
    )
    .unwrap();
    fb
}

fn triangle_soup(rng: &mut Rng, n: u32) -> (Vec<ClipVertex<0>>, Vec<[u32; 3]>) {
    let vertices = (0..3 * n).map(|_| random_vertex(rng)).collect();
    let triangles = (0..n).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    (vertices, triangles)
}

/// Shadow-volume passes take a dedicated counting path; it must give the
/// same stencil counts as the general path (forced here by a fragment
/// stage that shades) for z-fail and z-pass, on random overlapping
/// triangles of both facings and random depths over a random scene depth.
#[test]
fn counting_path_equals_general_stencil_path() {
    struct Shades;
    impl FragmentStage<0> for Shades {
        type Target = ();
        fn shade(&self, _: &FragmentBatch<0>, _: &mut ()) {}
    }
    let (w, h) = (150u32, 110u32);
    let mut rng = Rng(99);
    let (scene, scene_tris) = triangle_soup(&mut rng, 20);
    let (volume, volume_tris) = triangle_soup(&mut rng, 100);
    for zpass in [false, true] {
        // The states the shadow-volume technique itself uses.
        let state = penumbra::internal::shadow::kit::volumes::stencil_state(zpass);
        let run = |general: bool| {
            let grid = TileGrid::new(w, h).unwrap();
            let mut fb = scene_depth(grid, &scene, &scene_tris);
            let mut none = vec![(); grid.tile_count()];
            let nf = penumbra::internal::raster::NoFragmentStage;
            fb.clear_stencil(0);
            if general {
                draw(&mut fb, &mut none, &state, &volume, &volume_tris, &Shades).unwrap();
            } else {
                draw(&mut fb, &mut none, &state, &volume, &volume_tris, &nf).unwrap();
            }
            fb.stencil_image()
        };
        let (fast, general) = (run(false), run(true));
        assert!(fast.iter().any(|&s| s != 0));
        assert_eq!(fast, general, "zpass = {zpass}");
    }
}

/// Counting passes merge triangle pairs `[a, b, c], [a, c, d]` into quads
/// (shadow-volume sides come that way). The counts must equal the general
/// path's, which draws the two triangles: random convex and non-convex
/// quads, slivers, both windings, vertices on half pixels (pixel centres
/// exactly on shared edges), non-planar pairs (each triangle keeps its
/// own depth), over a scene depth that lets whole bands pass or fail.
#[test]
fn counting_path_merges_quads_exactly() {
    struct Shades;
    impl FragmentStage<0> for Shades {
        type Target = ();
        fn shade(&self, _: &FragmentBatch<0>, _: &mut ()) {}
    }
    let (w, h) = (190u32, 150u32);
    let mut rng = Rng(2024);
    let at = |x: f64, y: f64, z: f64| ClipVertex {
        position: Vec4::new(
            (2.0 * x / w as f64 - 1.0) as f32,
            (1.0 - 2.0 * y / h as f64) as f32,
            z as f32,
            1.0,
        ),
        varyings: [],
    };
    // Scene: a few large triangles at random depths.
    let mut scene = Vec::new();
    for _ in 0..12 {
        for _ in 0..3 {
            let (x, y) = (rng.range(-40, 230) as f64, rng.range(-40, 190) as f64);
            scene.push(at(x, y, 0.2 + 0.6 * rng.f64()));
        }
    }
    let scene_tris: Vec<[u32; 3]> = (0..12).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    let mut volume = Vec::new();
    let mut volume_tris = Vec::new();
    for q in 0..400 {
        let n = volume.len() as u32;
        let half = q % 3 == 0;
        let corner = |rng: &mut Rng| {
            let (mut x, mut y) = (rng.range(-20, 210) as f64, rng.range(-20, 170) as f64);
            if !half {
                x += rng.f64();
                y += rng.f64();
            } else {
                x += 0.5 * (rng.range(0, 1) as f64);
                y += 0.5 * (rng.range(0, 1) as f64);
            }
            (x, y)
        };
        let mut pts: Vec<(f64, f64)> = (0..4).map(|_| corner(&mut rng)).collect();
        if q % 4 == 1 {
            // A sliver: two far ends a few pixels wide.
            let (x, y) = pts[0];
            let (dx, dy) = (rng.range(-3, 3) as f64, rng.range(-3, 3) as f64);
            pts[1] = (x + dx + 0.5, y + 1.0 + dy.abs());
            pts[3] = (x - 1.5, y - 0.5);
        }
        for &(x, y) in &pts {
            volume.push(at(x, y, rng.f64()));
        }
        let (a, b, c, d) = (n, n + 1, n + 2, n + 3);
        if rng.next_u64() & 1 == 0 {
            volume_tris.push([a, b, c]);
            volume_tris.push([a, c, d]);
        } else {
            volume_tris.push([a, d, c]);
            volume_tris.push([a, c, b]);
        }
    }
    for zpass in [false, true] {
        let state = penumbra::internal::shadow::kit::volumes::stencil_state(zpass);
        let run = |general: bool| {
            let grid = TileGrid::new(w, h).unwrap();
            let mut fb = scene_depth(grid, &scene, &scene_tris);
            let mut none = vec![(); grid.tile_count()];
            let nf = penumbra::internal::raster::NoFragmentStage;
            fb.clear_stencil(0);
            let stats = if general {
                draw(&mut fb, &mut none, &state, &volume, &volume_tris, &Shades).unwrap()
            } else {
                draw(&mut fb, &mut none, &state, &volume, &volume_tris, &nf).unwrap()
            };
            (fb.stencil_image(), stats.setup_triangles)
        };
        let ((fast, merged), (general, separate)) = (run(false), run(true));
        assert!(
            merged < separate,
            "no quad was merged ({merged} of {separate})"
        );
        assert!(fast.iter().any(|&s| s != 0));
        assert_eq!(fast, general, "zpass = {zpass}");
    }
}

/// Shading passes without depth writes or stencil skip rectangles on depth
/// bounds. What they skip must be exactly what fails: the fragments
/// passing `Greater` and those passing `LessEqual` (its complement) are,
/// pixel by pixel, the covered fragments (`Always`), and each equals a
/// stage that runs every covered fragment and compares depths itself.
#[test]
fn depth_bounds_skip_only_failing_fragments() {
    struct Compare(CompareFunc);
    impl FragmentStage<0> for Compare {
        type Target = Box<[u32]>;
        fn shade(&self, batch: &FragmentBatch<0>, target: &mut Box<[u32]>) {
            let (d, s) = (batch.depth.to_array(), batch.stored_depth.to_array());
            for k in batch.lanes() {
                if self.0 == CompareFunc::Always || self.0.test(d[k], s[k]) {
                    target[batch.local + k] += 1;
                }
            }
        }
    }
    let (w, h) = (200u32, 170u32);
    let mut rng = Rng(77);
    let at = |x: f64, y: f64, z: f64| ClipVertex {
        position: Vec4::new(
            (2.0 * x / w as f64 - 1.0) as f32,
            (1.0 - 2.0 * y / h as f64) as f32,
            z as f32,
            1.0,
        ),
        varyings: [],
    };
    let mut scene = Vec::new();
    for _ in 0..30 {
        let (x, y) = (rng.range(-60, 260) as f64, rng.range(-60, 230) as f64);
        for _ in 0..3 {
            let (dx, dy) = (rng.range(-80, 80) as f64, rng.range(-80, 80) as f64);
            scene.push(at(x + dx, y + dy, 0.1 + 0.8 * rng.f64()));
        }
    }
    let scene_tris: Vec<[u32; 3]> = (0..30).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    let mut tris_v = Vec::new();
    for _ in 0..300 {
        let big = rng.range(0, 2) == 0;
        let r = if big { 150 } else { 12 };
        let (x, y) = (rng.range(-30, 230) as f64, rng.range(-30, 200) as f64);
        for _ in 0..3 {
            let (dx, dy) = (rng.range(-r, r) as f64, rng.range(-r, r) as f64);
            tris_v.push(at(x + dx + 0.5 * rng.f64(), y + dy, rng.f64()));
        }
    }
    let tris: Vec<[u32; 3]> = (0..300).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    let run = |func: CompareFunc, self_test: bool| {
        let grid = TileGrid::new(w, h).unwrap();
        let mut fb = scene_depth(grid, &scene, &scene_tris);
        let mut counts = TiledTarget::new(grid, 0u32);
        let state = RasterState {
            depth_func: if self_test { CompareFunc::Always } else { func },
            depth_write: false,
            stencil: None,
            cull: CullMode::None,
        };
        draw(
            &mut fb,
            counts.tiles_mut(),
            &state,
            &tris_v,
            &tris,
            &Compare(func),
        )
        .unwrap();
        counts.to_image()
    };
    let all = run(CompareFunc::Always, false);
    let front = run(CompareFunc::Greater, false);
    let behind = run(CompareFunc::LessEqual, false);
    assert!(front.iter().any(|&c| c > 0) && behind.iter().any(|&c| c > 0));
    for i in 0..all.len() {
        assert_eq!(front[i] + behind[i], all[i], "pixel {i}");
    }
    assert_eq!(front, run(CompareFunc::Greater, true));
    assert_eq!(behind, run(CompareFunc::LessEqual, true));
}

/// A depth-shift count ([`draw_depth_shift_counts`]) makes the plain
/// counts and, per scale, each pixel's change of count when its stored
/// depth `d` becomes `d × scale`, all in one walk: each change must be
/// exactly the plain count over a copy of the scene depth scaled that way
/// minus the plain count, for z-fail and z-pass, on random triangles and
/// merged quads (`[a, b, c], [a, c, d]`) over a random scene depth, with
/// scales large enough that many tests flip and small enough to be ties.
#[test]
fn depth_shift_counts_are_scaled_counts_minus_plain_ones() {
    let (w, h) = (170u32, 130u32);
    let mut rng = Rng(7);
    let (scene, scene_tris) = triangle_soup(&mut rng, 20);
    let (mut volume, mut volume_tris) = triangle_soup(&mut rng, 100);
    for _ in 0..60 {
        let n = volume.len() as u32;
        volume.extend((0..4).map(|_| random_vertex(&mut rng)));
        volume_tris.extend([[n, n + 1, n + 2], [n, n + 2, n + 3]]);
    }
    let grid = TileGrid::new(w, h).unwrap();
    for zpass in [false, true] {
        let state = penumbra::internal::shadow::kit::volumes::stencil_state(zpass);
        let plain = |scale: Option<f32>| {
            let mut fb = scene_depth(grid, &scene, &scene_tris);
            if let Some(s) = scale {
                fb.map_depth(|d| d * s);
            }
            fb.clear_stencil(0);
            let mut none = vec![(); grid.tile_count()];
            let nf = penumbra::internal::raster::NoFragmentStage;
            draw(&mut fb, &mut none, &state, &volume, &volume_tris, &nf).unwrap();
            fb.stencil_image()
        };
        let counts = plain(None);
        for scales in [
            vec![Some(1.08f32), Some(0.93), None],
            vec![Some(1.0 + 4e-6), None, Some(1.0 - 4e-6)],
            vec![Some(0.9)],
        ] {
            let mut fb = scene_depth(grid, &scene, &scene_tris);
            let images = penumbra::internal::raster::draw_depth_shift_counts(
                &mut fb,
                &state,
                &volume,
                &volume_tris,
                &scales,
            )
            .unwrap();
            assert_eq!(images.len(), scales.len());
            assert_eq!(
                fb.stencil_image(),
                counts,
                "the stencil holds the plain counts"
            );
            for (image, scale) in images.iter().zip(&scales) {
                match scale {
                    None => assert_eq!(image, &counts, "zpass = {zpass}"),
                    Some(s) => {
                        let want: Vec<i32> = plain(Some(*s))
                            .iter()
                            .zip(&counts)
                            .map(|(a, b)| a - b)
                            .collect();
                        assert_eq!(image, &want, "zpass = {zpass}, scale {s}");
                        if *s > 1.05 || *s < 0.95 {
                            assert!(image.iter().filter(|&&c| c != 0).count() > 100);
                        }
                    }
                }
            }
        }
    }
    // More distinct scales than one walk records (4): a parameter error.
    let mut fb = scene_depth(grid, &scene, &scene_tris);
    let state = penumbra::internal::shadow::kit::volumes::stencil_state(false);
    let five = [Some(1.1), Some(1.2), Some(1.3), Some(1.4), Some(1.5)];
    assert!(penumbra::internal::raster::draw_depth_shift_counts(
        &mut fb,
        &state,
        &volume,
        &volume_tris,
        &five
    )
    .is_err());
}
