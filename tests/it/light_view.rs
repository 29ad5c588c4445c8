//! Views from a light and depth maps of the casters: every texel of a
//! rasterized depth map against a ray cast from the eye through the texel
//! centre with the project's BVH.

use crate::common;

use glam::{DVec2, DVec3, Vec3};
use penumbra::internal::geom::bvh::Bvh;
use penumbra::internal::geom::SceneGeometry;
use penumbra::internal::scene::{Light, LightShape, Scene};
use penumbra::internal::shadow::kit::light_view::{
    caster_bounds, caster_depth_map, depth_map, receiver_bounds, LightView, MAX_TAN,
};
use penumbra::internal::view::{Extent, View};

/// A texel may disagree with its ray (hit against miss, or a different
/// surface) only if its centre lies within this many texels of the
/// projection of a drawn edge (a triangle's edge, or the cut of a triangle
/// by the near plane). The rasterizer snaps vertices to 1/256 texel (an
/// edge moves by at most ~0.003 texel) and rounds clip coordinates to f32;
/// the BVH test is f32 in world space.
const EDGE_TOLERANCE: f64 = 0.01;

/// Where both hit, the map's depth must equal the ray's in reversed Z
/// (`d = near / distance`, what the rasterizer interpolates, affine in
/// screen space) within
/// `DEPTH_TOLERANCE · d + DEPTH_SHIFT · |∇d| + PLANE_ROUNDING · d_max`:
/// relative rounding; a shift of the texel centre by `DEPTH_SHIFT` texels on
/// the hit triangle (`|∇d|`: the change of its `d` over one texel in x plus
/// one in y; the raster's depth plane has an f32 reference point, about
/// 2^-24 · 512 = 3e-5 texel off here, which moves the depth of a triangle
/// seen edge-on by far more than its own rounding); and the f32 rounding of
/// the plane's value at its reference vertex, `d_max` being the largest `d`
/// of the triangle's vertices, 1 for a vertex at or behind the near plane.
/// The last term matters only for triangles cut by a tiny near plane.
const DEPTH_TOLERANCE: f64 = 1e-6;
/// See `DEPTH_TOLERANCE`.
const DEPTH_SHIFT: f64 = 1e-3;
/// See `DEPTH_TOLERANCE`: 4 ulp at the reference value.
const PLANE_ROUNDING: f64 = 4.0 / (1u64 << 24) as f64;

/// What a check found.
#[derive(Debug, Default)]
struct Outcome {
    hits: usize,
    misses: usize,
    /// Texels that disagree, every one within `EDGE_TOLERANCE` of an edge.
    excused: usize,
    /// Largest relative error of the linear depth over the agreeing hits.
    max_rel: f64,
    /// Agreeing hits whose error exceeds the relative term alone.
    beyond_rel: usize,
}

/// The kept triangles' edges on the image, in texels: each triangle cut to
/// the near half-space first (in f64), so the near plane's cut is an edge
/// too.
fn projected_edges(
    geometry: &SceneGeometry,
    keep: &dyn Fn(u32) -> bool,
    view: &View,
) -> Vec<[DVec2; 2]> {
    let mut edges = Vec::new();
    for (t, tri) in geometry.triangles.iter().enumerate() {
        if !keep(t as u32) {
            continue;
        }
        let corners = tri.map(|i| geometry.positions[i as usize].as_dvec3());
        let mut poly = Vec::new();
        for k in 0..3 {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            let (da, db) = (view.depth_of(a) - view.near, view.depth_of(b) - view.near);
            if da >= 0.0 {
                poly.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                poly.push(a + (b - a) * (da / (da - db)));
            }
        }
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            // Points on the near plane may round just behind the eye's
            // plane only if near is 0, which a view never has.
            if let (Some(pa), Some(pb)) = (view.pixel_of(a), view.pixel_of(b)) {
                edges.push([pa, pb]);
            }
        }
    }
    edges
}

fn distance_to_segment(p: DVec2, [a, b]: [DVec2; 2]) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).length()
}

/// Renders the depth map of the kept triangles from `view` and compares
/// every texel with the closest BVH hit beyond the near plane along the
/// texel centre's primary ray.
fn check(geometry: &SceneGeometry, keep: &(dyn Fn(u32) -> bool + Sync), view: &View) -> Outcome {
    let map = depth_map(geometry, keep, view).expect("depth map");
    assert_eq!((map.width, map.height), (view.width, view.height));
    assert_eq!(
        map.memory_bytes(),
        4 * view.width as u64 * view.height as u64
    );
    let bvh = Bvh::build(geometry, keep);
    let eye = view.eye.as_vec3();
    assert_eq!(eye.as_dvec3(), view.eye, "test views have f32 eyes");
    let mut edges: Option<Vec<[DVec2; 2]>> = None;
    let mut out = Outcome::default();
    let mut failures = Vec::new();
    for j in 0..view.height {
        for i in 0..view.width {
            let dir = view.primary_ray(i, j);
            let along = dir.dot(view.forward);
            let mut reference = f64::INFINITY;
            let mut hit_triangle = u32::MAX;
            bvh.for_each_hit(eye, dir.as_vec3(), f32::MAX, |h| {
                // The BVH decides hit or miss (f32, watertight); the
                // distance is the f64 solve on the hit triangle's plane, so
                // the comparison measures the rasterizer's depth only.
                let frame = &geometry.frame(h.triangle);
                let t = frame.hit(view.eye, dir).map_or(h.t as f64, |f| f.0);
                let depth = t * along;
                if depth >= view.near && depth < reference {
                    reference = depth;
                    hit_triangle = h.triangle;
                }
            });
            let got = map.get(i, j) as f64;
            assert!(!got.is_nan(), "NaN depth at ({i}, {j})");
            let agree = if got.is_infinite() || reference.is_infinite() {
                got == reference
            } else {
                // Reversed Z of the hit triangle's plane at a screen point.
                let frame = &geometry.frame(hit_triangle);
                let win = view.window;
                let (w, h) = (view.width as f64, view.height as f64);
                let rz = |sx: f64, sy: f64| {
                    let d = view.forward
                        + (win.left + (win.right - win.left) * sx / w) * view.right
                        + (win.top - (win.top - win.bottom) * sy / h) * view.up;
                    let n = frame.normal;
                    view.near / (n.dot(frame.a - view.eye) / n.dot(d) * d.dot(view.forward))
                };
                let (cx, cy) = (i as f64 + 0.5, j as f64 + 0.5);
                let centre = rz(cx, cy);
                let per_texel =
                    (rz(cx + 1.0, cy) - centre).abs() + (rz(cx, cy + 1.0) - centre).abs();
                let d_max = geometry.triangles[hit_triangle as usize]
                    .iter()
                    .map(|&v| {
                        let z = view.depth_of(geometry.positions[v as usize].as_dvec3());
                        if z > view.near {
                            view.near / z
                        } else {
                            1.0
                        }
                    })
                    .fold(0.0, f64::max);
                let (rz_got, rz_ref) = (view.near / got, view.near / reference);
                let err = (rz_got - rz_ref).abs();
                let relative = DEPTH_TOLERANCE * rz_ref;
                if err <= relative + DEPTH_SHIFT * per_texel + PLANE_ROUNDING * d_max {
                    out.max_rel = out.max_rel.max((got - reference).abs() / reference);
                    out.beyond_rel += usize::from(err > relative);
                    true
                } else {
                    false
                }
            };
            if agree {
                if reference.is_finite() {
                    out.hits += 1;
                } else {
                    out.misses += 1;
                }
                continue;
            }
            let edges = edges.get_or_insert_with(|| projected_edges(geometry, keep, view));
            let centre = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
            let near_edge = edges
                .iter()
                .any(|&e| distance_to_segment(centre, e) <= EDGE_TOLERANCE);
            if near_edge {
                out.excused += 1;
            } else {
                failures.push((i, j, got, reference));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} texels disagree with ray casting away from edges, e.g. (i, j, map, ray) {:?}",
        failures.len(),
        &failures[..failures.len().min(10)]
    );
    let texels = (view.width * view.height) as usize;
    assert!(
        out.excused * 1000 <= texels,
        "{} of {texels} texels excused near edges: more than 0.1 %",
        out.excused
    );
    out
}

fn scene_geometry(name: &str) -> (Scene, SceneGeometry) {
    let scene = common::shipped(name);
    let geometry = SceneGeometry::new(&scene);
    (scene, geometry)
}

fn casters(scene: &Scene, geometry: &SceneGeometry) -> impl Fn(u32) -> bool + Sync {
    let casts: Vec<bool> = scene.objects.iter().map(|o| o.cast_shadows).collect();
    let objects = geometry.triangle_object.clone();
    move |t| casts[objects[t as usize] as usize]
}

fn rect(light: &Light) -> (Vec3, Vec3, Vec3) {
    match light.shape {
        LightShape::Rect { center, u, v, .. } => (center, u, v),
        LightShape::Sphere { .. } => panic!("test scenes have rect lights"),
    }
}

/// Every caster vertex that `lit` (in the point's emitting half-space)
/// and inside the receivers' bounds projects inside the image of a
/// complete light view (here the receivers' bounds hold all casters).
fn assert_holds_casters(scene: &Scene, lv: &LightView, lit: impl Fn(DVec3) -> bool) {
    let v = &lv.view;
    for o in scene.objects.iter().filter(|o| o.cast_shadows) {
        for p in o.mesh.positions.iter().filter(|p| lit(p.as_dvec3())) {
            let px = v
                .pixel_of(p.as_dvec3())
                .expect("caster in front of the light");
            assert!(
                (0.0..=v.width as f64).contains(&px.x) && (0.0..=v.height as f64).contains(&px.y),
                "caster vertex {p} lands at {px}, outside {}×{}",
                v.width,
                v.height
            );
            assert!(v.depth_of(p.as_dvec3()) >= v.near);
        }
    }
}

#[test]
fn rect_light_views_match_ray_casting_on_quad_and_spheres() {
    for (name, size) in [("quad.toml", (256, 256)), ("spheres.toml", (512, 384))] {
        let (scene, geometry) = scene_geometry(name);
        let keep = casters(&scene, &geometry);
        let light = &scene.lights[0];
        let (c, u, v) = rect(light);
        let n = u.cross(v).normalize().as_dvec3();
        for point in [c, c + u + v, c - 0.5 * u + 0.25 * v] {
            let lv = LightView::from_rect_light(
                light,
                point,
                caster_bounds(&scene).unwrap(),
                receiver_bounds(&scene).unwrap(),
                size,
            )
            .expect("valid input")
            .expect("casters in front of the light");
            assert!(lv.complete, "{name}: the casters are all below the light");
            assert_eq!(lv.view.eye, point.as_dvec3());
            assert!(
                (lv.view.forward - n).length() < 1e-12,
                "{name}: looks along the emitting normal"
            );
            assert!(!lv.view.symmetric);
            assert_holds_casters(&scene, &lv, |_| true);
            let out = check(&geometry, &keep, &lv.view);
            eprintln!("{name} from {point}: {out:?}");
            let texels = (size.0 * size.1) as usize;
            assert!(out.hits * 10 > texels, "{name}: the casters fill the view");
            // The library's own filter (cast_shadows) gives the same map.
            let a = caster_depth_map(&scene, &geometry, &lv.view).unwrap();
            let b = depth_map(&geometry, &keep, &lv.view).unwrap();
            assert!(a
                .as_slice()
                .iter()
                .zip(b.as_slice())
                .all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
}

#[test]
fn rect_light_view_matches_ray_casting_on_the_bunny() {
    let (scene, geometry) = scene_geometry("bunny.toml");
    // Only the bunny casts here, so the fitted frustum is the bunny's.
    let bunny = scene
        .objects
        .iter()
        .position(|o| o.name != "ground")
        .unwrap();
    let keep = {
        let objects = geometry.triangle_object.clone();
        move |t: u32| objects[t as usize] as usize == bunny
    };
    let mesh = &scene.objects[bunny].mesh;
    let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, p| a.min(*p));
    let hi = mesh
        .positions
        .iter()
        .fold(Vec3::NEG_INFINITY, |a, p| a.max(*p));
    let light = &scene.lights[0];
    let (c, u, v) = rect(light);
    let lv = LightView::from_rect_light(
        light,
        c - 0.8 * u + 0.6 * v,
        (lo, hi),
        receiver_bounds(&scene).unwrap(),
        (384, 384),
    )
    .unwrap()
    .unwrap();
    assert!(lv.complete);
    let out = check(&geometry, &keep, &lv.view);
    eprintln!("bunny: {out:?}");
    assert!(out.hits * 4 > 384 * 384, "the bunny fills its fitted view");
    assert!(out.misses > 0);
}

#[test]
fn sphere_light_view_matches_ray_casting() {
    let (scene, geometry) = scene_geometry("spheres.toml");
    let keep = casters(&scene, &geometry);
    let (center, radius) = (Vec3::new(2.0, 7.0, 1.0), 0.5);
    let light = Light {
        shape: LightShape::Sphere { center, radius },
        radiance: Vec3::ONE,
        texture: None,
    };
    // A point on the lower side (facing the spheres), one on the side.
    for dir in [Vec3::new(-0.3, -1.0, 0.2), Vec3::new(1.0, -0.2, 0.0)] {
        let point = center + dir.normalize() * radius;
        let lv = LightView::from_sphere_light(
            &light,
            point,
            caster_bounds(&scene).unwrap(),
            receiver_bounds(&scene).unwrap(),
            (320, 320),
        )
        .unwrap()
        .unwrap();
        let f = lv.view.forward;
        let bounds = caster_bounds(&scene).unwrap();
        let toward = (0.5 * (bounds.0 + bounds.1) - point).as_dvec3().normalize();
        assert!(f.dot(toward) > 0.5, "looks toward the casters");
        assert!(lv.view.window.left.abs() <= MAX_TAN);
        let out = check(&geometry, &keep, &lv.view);
        eprintln!(
            "sphere light from {point}: {out:?} complete {}",
            lv.complete
        );
        assert!(out.hits * 10 > 320 * 320);
        assert!(
            lv.complete,
            "the casters' cut bounds are far from the point"
        );
        let (p, n) = (point.as_dvec3(), (point - center).as_dvec3());
        assert_holds_casters(&scene, &lv, |q| (q - p).dot(n) > 0.0);
    }
    // From the top of the sphere, the casters are behind the tangent plane.
    let top = center + Vec3::Y * radius;
    let none = LightView::from_sphere_light(
        &light,
        top,
        caster_bounds(&scene).unwrap(),
        receiver_bounds(&scene).unwrap(),
        (64, 64),
    )
    .unwrap();
    assert!(
        none.is_none(),
        "nothing below the top's tangent plane is lit"
    );
}

#[test]
fn off_axis_frustum_matches_ray_casting_and_its_own_rays() {
    let (scene, geometry) = scene_geometry("spheres.toml");
    let keep = casters(&scene, &geometry);
    let near = 0.25;
    let view = View::from_frustum(
        DVec3::new(6.0, 3.0, 6.5),
        DVec3::new(-1.0, -0.25, -1.0),
        DVec3::Y,
        Extent::Window {
            left: -0.1,
            right: 0.3,
            bottom: -0.15,
            top: 0.1,
        },
        300,
        200,
        near,
    )
    .unwrap();
    assert!(!view.symmetric);
    // The texel grid is the window: centres' rays land on texel centres,
    // and the clip-space projection the rasterizer uses puts them there too.
    for (i, j) in [(0, 0), (299, 0), (0, 199), (299, 199), (123, 77)] {
        let p = view.eye + view.primary_ray(i, j) * 7.0;
        let px = view.pixel_of(p).unwrap();
        let want = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
        assert!((px - want).length() < 1e-9, "{px} vs {want}");
        let c = view.clip_point(p.as_vec3()).as_dvec4();
        let raster = DVec2::new(
            (c.x / c.w * 0.5 + 0.5) * 300.0,
            (0.5 - c.y / c.w * 0.5) * 200.0,
        );
        assert!((raster - want).length() < 1e-3, "{raster} vs {want}");
        assert!((c.z / c.w - near / view.depth_of(p)).abs() < 1e-6);
    }
    let out = check(&geometry, &keep, &view);
    eprintln!("off-axis: {out:?}");
    assert!(out.hits > 0 && out.misses > 0);
}

#[test]
fn casters_straddling_the_light_plane_are_cut_at_a_small_near() {
    let (scene, geometry) = scene_geometry("spheres.toml");
    let keep = casters(&scene, &geometry);
    // A light at the spheres' centre height, facing down: every sphere
    // straddles its plane.
    let light = Light {
        shape: LightShape::Rect {
            center: Vec3::new(0.5, 1.5, 0.5),
            u: Vec3::new(0.1, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, 0.1),
            two_sided: false,
        },
        radiance: Vec3::ONE,
        texture: None,
    };
    let (lo, hi) = caster_bounds(&scene).unwrap();
    let lv = LightView::from_rect_light(
        &light,
        Vec3::new(0.5, 1.5, 0.5),
        (lo, hi),
        receiver_bounds(&scene).unwrap(),
        (256, 256),
    )
    .unwrap()
    .unwrap();
    let v = &lv.view;
    assert!(!lv.complete, "casters touch the plane: cut off");
    assert!(v.near > 0.0 && v.near < 1e-3, "near {}", v.near);
    let w = v.window;
    for t in [w.left, w.right, w.bottom, w.top] {
        assert!(t.is_finite() && t.abs() <= MAX_TAN * 1.001, "window {w:?}");
    }
    let out = check(&geometry, &keep, v);
    eprintln!("straddling: {out:?}");
    assert!(out.hits > 0);
    // The same light turned up (two-sided picks the casters' side: the
    // centre of the bounds is below, so it still looks down).
    let two = Light {
        shape: LightShape::Rect {
            center: Vec3::new(0.5, 1.5, 0.5),
            u: Vec3::new(0.0, 0.0, 0.1),
            v: Vec3::new(0.1, 0.0, 0.0),
            two_sided: true,
        },
        ..light.clone()
    };
    let lv2 = LightView::from_rect_light(
        &two,
        Vec3::new(0.5, 1.5, 0.5),
        (lo, hi),
        receiver_bounds(&scene).unwrap(),
        (64, 64),
    )
    .unwrap()
    .unwrap();
    assert!(lv2.view.forward.y < -0.999);
    // One-sided and facing up: only the spheres' tops are in front.
    let up = Light {
        shape: LightShape::Rect {
            center: Vec3::new(0.5, 1.5, 0.5),
            u: Vec3::new(0.0, 0.0, 0.1),
            v: Vec3::new(0.1, 0.0, 0.0),
            two_sided: false,
        },
        ..light.clone()
    };
    let lv3 =
        LightView::from_rect_light(&up, Vec3::new(0.5, 1.5, 0.5), (lo, hi), (lo, hi), (64, 64))
            .unwrap()
            .unwrap();
    assert!(lv3.view.forward.y > 0.999 && !lv3.complete);
    // Casters wholly behind the light: nothing to draw.
    let above = (Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 3.0, 1.0));
    let none = LightView::from_rect_light(
        &light,
        Vec3::new(0.5, 1.5, 0.5),
        above,
        receiver_bounds(&scene).unwrap(),
        (64, 64),
    )
    .unwrap();
    assert!(none.is_none());
}

#[test]
fn the_camera_path_of_from_frustum_is_the_camera_view() {
    let scene = common::shipped("bunny.toml");
    let cam = scene.camera;
    let a = View::new(&cam, 640, 360, 1e-3).unwrap();
    let b = View::from_frustum(
        cam.eye.as_dvec3(),
        cam.target.as_dvec3() - cam.eye.as_dvec3(),
        cam.up.as_dvec3(),
        Extent::FovY {
            degrees: cam.fov_y_degrees as f64,
        },
        640,
        360,
        1e-3,
    )
    .unwrap();
    assert!(a.symmetric && b.symmetric);
    assert_eq!(a.forward, b.forward);
    assert_eq!(a.tan_half_fov, b.tan_half_fov);
    for p in [Vec3::new(0.3, 0.4, -0.2), Vec3::new(-2.0, 0.0, 1.0)] {
        assert_eq!(a.clip_point(p), b.clip_point(p));
    }
    for (i, j) in [(0, 0), (639, 359), (17, 300)] {
        assert_eq!(a.primary_ray(i, j), b.primary_ray(i, j));
        let px = a.pixel_of(a.eye + a.primary_ray(i, j) * 3.0).unwrap();
        assert!((px - DVec2::new(i as f64 + 0.5, j as f64 + 0.5)).length() < 1e-9);
    }
}

#[test]
fn bad_input_is_an_error() {
    let (scene, geometry) = scene_geometry("quad.toml");
    let light = &scene.lights[0];
    let (c, u, _) = rect(light);
    let (cb, rb) = (
        caster_bounds(&scene).unwrap(),
        receiver_bounds(&scene).unwrap(),
    );
    let err = |r: penumbra::internal::error::Result<Option<LightView>>| r.unwrap_err().to_string();
    for size in [(0, 16), (16, 0), (20000, 1), (8193, 8192)] {
        let e = err(LightView::from_rect_light(light, c, cb, rb, size));
        assert!(e.contains("size"), "{e}");
    }
    let e = err(LightView::from_rect_light(
        light,
        c + u * 3.0,
        cb,
        rb,
        (8, 8),
    ));
    assert!(e.contains("point_on_light"), "{e}");
    let e = err(LightView::from_rect_light(
        light,
        c + Vec3::Y * 0.5,
        cb,
        rb,
        (8, 8),
    ));
    assert!(e.contains("point_on_light"), "{e}");
    let e = err(LightView::from_sphere_light(light, c, cb, rb, (8, 8)));
    assert!(e.contains("sphere light"), "{e}");
    let e = err(LightView::from_rect_light(
        light,
        c,
        (Vec3::ONE, Vec3::ZERO),
        rb,
        (8, 8),
    ));
    assert!(e.contains("casters_bounds"), "{e}");
    let e = err(LightView::from_rect_light(
        light,
        c,
        cb,
        (Vec3::ZERO, Vec3::splat(f32::NAN)),
        (8, 8),
    ));
    assert!(e.contains("receivers_bounds"), "{e}");
    // A view too large for a depth map is refused before drawing.
    let big = View::from_frustum(
        DVec3::new(0.0, 4.0, 0.0),
        -DVec3::Y,
        DVec3::Z,
        Extent::FovY { degrees: 60.0 },
        16384,
        16384,
        0.1,
    )
    .unwrap();
    let e = depth_map(&geometry, |_| true, &big)
        .unwrap_err()
        .to_string();
    assert!(e.contains("size"), "{e}");
    // Degenerate frusta.
    for extent in [
        Extent::Window {
            left: 0.1,
            right: 0.1,
            bottom: -0.1,
            top: 0.1,
        },
        Extent::Window {
            left: -0.1,
            right: 0.1,
            bottom: f64::NAN,
            top: 0.1,
        },
        Extent::FovY { degrees: 180.0 },
    ] {
        assert!(View::from_frustum(DVec3::ZERO, DVec3::X, DVec3::Y, extent, 8, 8, 0.1).is_err());
    }
    assert!(View::from_frustum(
        DVec3::ZERO,
        DVec3::Y,
        DVec3::Y,
        Extent::FovY { degrees: 60.0 },
        8,
        8,
        0.1
    )
    .is_err());
}
