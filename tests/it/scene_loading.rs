//! Scene loading through the public API: every error class names the file
//! and line at fault, and the contract's conventions (shapes, transforms,
//! materials, textures) hold on loaded scenes.

use crate::common;

use glam::{Vec2, Vec3};
use penumbra::internal::scene::{load_scene, LightShape, Scene, TextureData};
use penumbra::Error;
use std::path::{Path, PathBuf};

use common::ScratchDir as Dir;

/// This file's own uses of a scratch directory.
trait SceneDir {
    fn load(&self, body: &str) -> penumbra::Result<Scene>;
}

impl SceneDir for Dir {
    /// Writes `scene.toml` (camera block prepended) and loads it.
    fn load(&self, body: &str) -> penumbra::Result<Scene> {
        load_scene(&self.write("scene.toml", format!("{CAMERA}{body}")))
    }
}

/// Lines 1–5 of every test scene; bodies start at line 6.
const CAMERA: &str = "[camera]
eye = [0.0, 2.0, 5.0]
target = [0.0, 0.0, 0.0]
fov_y = 45.0
width = 64
";

/// Asserts an `Error::File` at `file:line` whose message contains `needle`.
#[track_caller]
fn assert_error<T: std::fmt::Debug>(
    r: penumbra::Result<T>,
    file: &Path,
    line: usize,
    needle: &str,
) {
    match r {
        Err(Error::File {
            path,
            line: l,
            message,
        }) => {
            assert_eq!(path, file, "wrong file; message: {message}");
            assert_eq!(l, Some(line), "wrong line; message: {message}");
            assert!(
                message.contains(needle),
                "message `{message}` lacks `{needle}`"
            );
        }
        other => panic!("expected a file error, got {other:?}"),
    }
}

/// Loads `body` in a fresh directory and asserts an error at `scene.toml:line`.
#[track_caller]
fn assert_scene_error(test: &str, body: &str, line: usize, needle: &str) {
    let dir = Dir::new(test);
    let r = dir.load(body);
    assert_error(r, &dir.0.join("scene.toml"), line, needle);
}

const TRIANGLE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

// ------------------------------------------------------------ errors ----

#[test]
fn toml_syntax_error_names_line() {
    assert_scene_error("syntax", "\n[[object]\nshape = \"box\"\n", 7, "");
}

#[test]
fn unknown_keys_are_errors() {
    assert_scene_error("unknown-cam", "colour = 3\n", 6, "unknown field `colour`");
    assert_scene_error(
        "unknown-obj",
        "[[object]]\nshape = \"box\"\nsize = [1, 1, 1]\nspin = 2\n",
        9,
        "spin",
    );
    assert_scene_error(
        "unknown-mat",
        "[[object]]\nshape = \"box\"\nmaterial = { albedo = 0.5, roughness = 1 }\n",
        8,
        "roughness",
    );
}

#[test]
fn wrong_types_are_errors() {
    let dir = Dir::new("type-fov");
    let path = dir.write(
        "scene.toml",
        "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nfov_y = \"wide\"\n",
    );
    assert_error(load_scene(&path), &path, 4, "");
    assert_scene_error(
        "type-scale",
        "[[object]]\nshape = \"box\"\nscale = \"big\"\n",
        8,
        "a number or an array of 3",
    );
    assert_scene_error(
        "type-len",
        "[[light]]\ntype = \"rect\"\ncenter = [0, 1]\n",
        8,
        "",
    );
}

#[test]
fn missing_obj_file() {
    assert_scene_error(
        "missing-obj",
        "\n[[object]]\nobj = \"nope.obj\"\n",
        8,
        "nope.obj",
    );
}

#[test]
fn missing_mtl_names_it_and_the_mtllib_line() {
    let dir = Dir::new("missing-mtl");
    let obj = dir.write("m.obj", format!("# model\nmtllib gone.mtl\n{TRIANGLE_OBJ}"));
    assert_error(
        dir.load("[[object]]\nobj = \"m.obj\"\n"),
        &obj,
        2,
        "gone.mtl",
    );
}

#[test]
fn malformed_obj_lines() {
    let cases = [
        (
            "bad-number",
            "v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n",
            2,
            "malformed number `x`",
        ),
        ("few-coords", "v 0 0 0\nv 1 0\n", 2, "malformed `v`"),
        (
            "out-of-range",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
            5,
            "out of range",
        ),
        (
            "relative",
            "v 0 0 0\nv 1 0 0\nf -1 -2 -4\nv 0 1 0\n",
            3,
            "relative face index -4",
        ),
        (
            "index-zero",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            4,
            "index 0",
        ),
        (
            "bad-index",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3x\n",
            4,
            "malformed face index",
        ),
        (
            "uv-range",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
            5,
            "texture coordinates",
        ),
        (
            "nan",
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
            2,
            "non-finite",
        ),
        (
            "inf",
            "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n",
            3,
            "non-finite",
        ),
        ("malformed-normal", "vn 0 x 1\n", 1, "malformed number `x`"),
        ("zero-w", "v 1 2 3 0\n", 1, "zero w"),
        ("usemtl", "usemtl\n", 1, "without a name"),
    ];
    for (name, obj_text, line, needle) in cases {
        let dir = Dir::new(&format!("obj-{name}"));
        let obj = dir.write("m.obj", obj_text);
        assert_error(
            dir.load("[[object]]\nobj = \"m.obj\"\n"),
            &obj,
            line,
            needle,
        );
    }
}

#[test]
fn malformed_mtl_lines() {
    let cases = [
        ("kd-two", "newmtl a\nKd 0.5 0.5\n", 2, "1 or 3 numbers"),
        ("kd-nan", "newmtl a\nKd 0.5 nan 0.5\n", 2, "non-finite"),
        ("d-range", "newmtl a\n\nd 1.5\n", 3, "[0, 1]"),
        ("map-empty", "newmtl a\nmap_Kd\n", 2, "without a file name"),
    ];
    for (name, mtl_text, line, needle) in cases {
        let dir = Dir::new(&format!("mtl-{name}"));
        dir.write("m.obj", format!("mtllib m.mtl\nusemtl a\n{TRIANGLE_OBJ}"));
        let mtl = dir.write("m.mtl", mtl_text);
        assert_error(
            dir.load("[[object]]\nobj = \"m.obj\"\n"),
            &mtl,
            line,
            needle,
        );
    }
}

#[test]
fn missing_and_corrupt_textures() {
    // Referenced from an MTL: the error points at the map_Kd line.
    let dir = Dir::new("tex-mtl");
    dir.write(
        "m.obj",
        format!("mtllib m.mtl\nusemtl a\n{TRIANGLE_OBJ}vt 0 0\n"),
    );
    let mtl = dir.write("m.mtl", "newmtl a\nKd 1 1 1\nmap_Kd textures/none.png\n");
    assert_error(
        dir.load("[[object]]\nobj = \"m.obj\"\n"),
        &mtl,
        3,
        "none.png",
    );

    // Referenced from the scene: the error points at the key's line.
    let dir = Dir::new("tex-corrupt");
    dir.write("bad.png", b"\x89PNG\r\n\x1a\nthis is not a png");
    dir.write("bad.jpg", b"not a jpeg either");
    let scene = dir.0.join("scene.toml");
    let body = "[[object]]\nshape = \"quad\"\nmaterial = { albedo_texture = \"bad.png\" }\n";
    assert_error(dir.load(body), &scene, 8, "bad.png");
    let body = "[[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nu = [1, 0, 0]\nv = [0, 0, 1]\nradiance = 1\ntexture = \"bad.jpg\"\n";
    assert_error(dir.load(body), &scene, 12, "bad.jpg");
}

#[test]
fn non_finite_scene_numbers() {
    assert_scene_error(
        "nan-toml",
        "[[object]]\nshape = \"box\"\ntranslate = [nan, 0, 0]\n",
        8,
        "finite",
    );
    assert_scene_error(
        "inf-toml",
        "[[object]]\nshape = \"box\"\nscale = inf\n",
        8,
        "finite",
    );
    assert_scene_error("inf-eye", "[scene]\nambient = [0, -inf, 0]\n", 7, "finite");
}

#[test]
fn field_of_view_is_open_interval() {
    for (fov, name) in [("0.0", "fov0"), ("180", "fov180"), ("-5", "fovneg")] {
        let dir = Dir::new(name);
        let path = dir.write(
            "scene.toml",
            format!("[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\n\nfov_y = {fov}\n"),
        );
        assert_error(load_scene(&path), &path, 5, "(0, 180)");
    }
}

#[test]
fn degenerate_lights() {
    let rect = |u: &str, v: &str| {
        format!("[[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nu = {u}\nv = {v}\nradiance = [1, 1, 1]\n")
    };
    assert_scene_error(
        "light-parallel",
        &rect("[1, 0, 0]", "[2, 0, 0]"),
        10,
        "zero area",
    );
    assert_scene_error(
        "light-zero",
        &rect("[0, 0, 0]", "[0, 0, 1]"),
        9,
        "zero area",
    );
    assert_scene_error(
        "light-sliver",
        &rect("[1, 0, 0]", "[1, 1e-9, 0]"),
        10,
        "zero area",
    );
    let sphere = |r: &str| {
        format!("[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = {r}\nradiance = 1\n")
    };
    assert_scene_error("light-radius", &sphere("0"), 9, "positive");
    assert_scene_error("light-radius-neg", &sphere("-1"), 9, "positive");
    let body = "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1\nradiance = 1\ntexture = \"t.png\"\n";
    assert_scene_error("light-sphere-tex", body, 11, "`texture` does not apply");
    let body = "[[light]]\ntype = \"spot\"\ncenter = [0, 3, 0]\nradiance = 1\n";
    assert_scene_error("light-type", body, 7, "unknown light type `spot`");
    let body =
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1\nradiance = [1, -1, 1]\n";
    assert_scene_error("light-negative", body, 10, "negative");
    assert_scene_error(
        "light-no-uv",
        "[[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nradiance = 1\n",
        6,
        "needs `u`",
    );
}

#[test]
fn absurd_sizes_are_refused() {
    let camera = |w: &str, h: &str| {
        format!("[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nfov_y = 45\nwidth = {w}\nheight = {h}\n")
    };
    for (w, h, line, needle, name) in [
        // One limit with `--width`/`--height`: the rasterizer's 16384.
        ("70000", "16", 5, "outside 1..=16384", "huge-w"),
        ("16385", "16", 5, "outside 1..=16384", "just-over-w"),
        ("16", "16385", 6, "outside 1..=16384", "just-over-h"),
        ("0", "16", 5, "outside", "zero-w"),
        ("16", "-3", 6, "outside", "neg-h"),
    ] {
        let dir = Dir::new(name);
        let path = dir.write("scene.toml", camera(w, h));
        assert_error(load_scene(&path), &path, line, needle);
    }
    // A TGA header claiming 65535 × 65535 texels, refused before decoding.
    let dir = Dir::new("huge-texture");
    let mut tga = vec![
        0u8, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff, 24, 0,
    ];
    tga.extend([0; 16]);
    dir.write("huge.tga", tga);
    let body = "[[object]]\nshape = \"box\"\nmaterial = { albedo_texture = \"huge.tga\" }\n";
    assert_error(dir.load(body), &dir.0.join("scene.toml"), 8, "limit");
    assert_scene_error(
        "segments",
        "[[object]]\nshape = \"sphere\"\nsegments = 5000\n",
        8,
        "3..=4096",
    );
    assert_scene_error(
        "segments-low",
        "[[object]]\nshape = \"sphere\"\nsegments = 2\n",
        8,
        "3..=4096",
    );
    assert_scene_error(
        "rings",
        "[[object]]\nshape = \"sphere\"\nrings = 1\n",
        8,
        "2..=4096",
    );
}

#[test]
fn semantic_object_errors() {
    let cases = [
        (
            "both",
            "[[object]]\nobj = \"a.obj\"\nshape = \"box\"\n",
            8,
            "not both",
        ),
        (
            "neither",
            "[[object]]\ntranslate = [1, 2, 3]\n",
            6,
            "needs `obj` or `shape`",
        ),
        (
            "shape",
            "[[object]]\nshape = \"torus\"\n",
            7,
            "unknown shape `torus`",
        ),
        (
            "zero-scale",
            "[[object]]\nshape = \"box\"\nscale = [1, 0, 1]\n",
            8,
            "zero",
        ),
        (
            "radius-on-box",
            "[[object]]\nshape = \"box\"\nradius = 2\n",
            8,
            "`radius` does not apply",
        ),
        (
            "size-len",
            "[[object]]\nshape = \"quad\"\nsize = [1, 2, 3]\n",
            8,
            "2 positive numbers",
        ),
        (
            "sphere-r",
            "[[object]]\nshape = \"sphere\"\nradius = -1\n",
            8,
            "positive",
        ),
        (
            "opacity",
            "[[object]]\nshape = \"box\"\nmaterial = { opacity = 1.5 }\n",
            8,
            "[0, 1]",
        ),
        (
            "albedo",
            "[[object]]\nshape = \"box\"\nmaterial = { albedo = [0.5, -0.1, 0] }\n",
            8,
            "negative",
        ),
    ];
    for (name, body, line, needle) in cases {
        assert_scene_error(name, body, line, needle);
    }
}

#[test]
fn degenerate_cameras() {
    let dir = Dir::new("cam-eye");
    let path = dir.write(
        "scene.toml",
        "[camera]\neye = [1, 2, 3]\ntarget = [1, 2, 3]\nfov_y = 45\n",
    );
    assert_error(load_scene(&path), &path, 3, "differ");
    let path = dir.write(
        "scene.toml",
        "[camera]\neye = [0, 5, 0]\ntarget = [0, 0, 0]\nup = [0, 2, 0]\nfov_y = 45\n",
    );
    assert_error(load_scene(&path), &path, 4, "parallel");
}

#[test]
fn unreadable_scene_is_io_error() {
    let r = load_scene(Path::new("/nonexistent/penumbra/scene.toml"));
    assert!(matches!(r, Err(Error::Io { .. })), "{r:?}");
}

// ---------------------------------------------------------- positives ----

#[test]
fn defaults() {
    let dir = Dir::new("defaults");
    let path = dir.write(
        "my-scene.toml",
        "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nfov_y = 45\n[[object]]\nshape = \"sphere\"\n",
    );
    let s = load_scene(&path).unwrap();
    assert_eq!(s.name, "my-scene");
    assert_eq!((s.camera.width, s.camera.height), (1024, 1024));
    assert_eq!(s.camera.up, Vec3::Y);
    assert_eq!((s.ambient, s.background), (Vec3::ZERO, Vec3::ZERO));
    let o = &s.objects[0];
    assert!(o.cast_shadows && o.receive_shadows);
    assert_eq!(o.mesh.triangle_count(), 2 * 20 * 19);
    let m = &s.materials[o.mesh.material_ids[0] as usize];
    assert_eq!(m.albedo, Vec3::splat(0.8));
    assert_eq!((m.specular, m.opacity), (Vec3::ZERO, 1.0));
    assert!(m.albedo_texture.is_none() && m.opacity_texture.is_none());
    for p in &o.mesh.positions {
        assert!((p.length() - 1.0).abs() < 1e-6);
    }
}

/// Every triangle's winding normal points away from `inside`.
fn assert_outward(s: &Scene, inside: Vec3) {
    let mesh = &s.objects[0].mesh;
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.corners(t);
        let n = mesh.face_normal(t);
        assert!(
            n.dot((a + b + c) / 3.0 - inside) > 0.0,
            "triangle {t} faces inward"
        );
    }
}

#[test]
fn sphere_matches_contract() {
    let dir = Dir::new("sphere");
    let c = Vec3::new(1.0, 2.0, 3.0);
    let s = dir
        .load("[[object]]\nshape = \"sphere\"\nradius = 0.5\nsegments = 7\nrings = 5\ntranslate = [1, 2, 3]\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangle_count(), 2 * 7 * (5 - 1));
    assert_outward(&s, c);
    let normals = mesh.normals.as_ref().unwrap();
    let uvs = mesh.uvs.as_ref().unwrap();
    for ((p, n), uv) in mesh.positions.iter().zip(normals).zip(uvs) {
        let d = *p - c;
        assert!((d.length() - 0.5).abs() < 1e-6);
        assert!((*n - d / 0.5).length() < 1e-5, "normal not radial");
        // uv = (phi / 2pi, 1 - theta / pi) with the contract's position formula.
        let theta = (d.y / 0.5).clamp(-1.0, 1.0).acos();
        assert!((uv.y - (1.0 - theta / std::f32::consts::PI)).abs() < 1e-5);
        if theta.sin() > 1e-3 && uv.x > 1e-6 && uv.x < 1.0 - 1e-6 {
            let phi = (-d.z).atan2(d.x).rem_euclid(std::f32::consts::TAU);
            assert!((uv.x - phi / std::f32::consts::TAU).abs() < 1e-5);
        }
    }
    // Vertex (k=1, m=1): theta = pi/5, phi = 2pi/7, z = -r sin(theta) sin(phi).
    let (t, f) = (std::f32::consts::PI / 5.0, std::f32::consts::TAU / 7.0);
    let want = c + 0.5 * Vec3::new(t.sin() * f.cos(), t.cos(), -t.sin() * f.sin());
    assert!(mesh.positions.iter().any(|p| (*p - want).length() < 1e-6));
    // Poles exactly on the axis.
    assert!(mesh
        .positions
        .iter()
        .any(|p| *p == c + Vec3::new(0.0, 0.5, 0.0)));
    assert!(mesh
        .positions
        .iter()
        .any(|p| *p == c - Vec3::new(0.0, 0.5, 0.0)));
}

#[test]
fn mirrored_scale_keeps_outward_winding() {
    let dir = Dir::new("mirror");
    let s = dir
        .load("[[object]]\nshape = \"sphere\"\nscale = [-1, 1, 1]\n")
        .unwrap();
    assert_outward(&s, Vec3::ZERO);
    let mesh = &s.objects[0].mesh;
    for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
        assert!((*n - *p).length() < 1e-5);
    }
}

#[test]
fn box_has_twelve_outward_triangles() {
    let dir = Dir::new("box");
    let s = dir
        .load("[[object]]\nshape = \"box\"\nsize = [2, 4, 6]\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangle_count(), 12);
    assert_eq!(mesh.positions.len(), 24);
    assert_outward(&s, Vec3::ZERO);
    for p in &mesh.positions {
        assert_eq!(p.abs(), Vec3::new(1.0, 2.0, 3.0));
    }
    // Flat normals equal to each triangle's winding normal.
    let normals = mesh.normals.as_ref().unwrap();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let n = mesh.face_normal(t).normalize();
        assert!(tri
            .iter()
            .all(|&i| (normals[i as usize] - n).length() < 1e-6));
    }
    // Each face's four corners cover the unit uv square.
    let uvs = mesh.uvs.as_ref().unwrap();
    for face in uvs.chunks(4) {
        let (lo, hi) = face.iter().fold((Vec2::ONE, Vec2::ZERO), |(l, h), uv| {
            (l.min(*uv), h.max(*uv))
        });
        assert_eq!((lo, hi), (Vec2::ZERO, Vec2::ONE));
    }
}

#[test]
fn quad_faces_up_with_contract_uvs() {
    let dir = Dir::new("quad");
    let s = dir
        .load("[[object]]\nshape = \"quad\"\nsize = [2, 4]\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangle_count(), 2);
    for t in 0..2 {
        let n = mesh.face_normal(t);
        assert!(n.normalize().abs_diff_eq(Vec3::Y, 1e-6), "{n}");
    }
    let uvs = mesh.uvs.as_ref().unwrap();
    for (p, uv) in mesh.positions.iter().zip(uvs) {
        assert_eq!(p.y, 0.0);
        assert_eq!((p.x.abs(), p.z.abs()), (1.0, 2.0));
        assert_eq!(*uv, Vec2::new(p.x / 2.0 + 0.5, 0.5 - p.z / 4.0));
    }
    assert!(mesh.normals.as_ref().unwrap().iter().all(|n| *n == Vec3::Y));
}

#[test]
fn transform_order_is_scale_rotate_xyz_translate() {
    let dir = Dir::new("transform");
    let s = dir
        .load("[[object]]\nshape = \"quad\"\nsize = [2, 2]\nscale = [2, 1, 1]\nrotate = [90, 90, 0]\ntranslate = [10, 0, 0]\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    // Corner (1, 0, 1): scale → (2, 0, 1); X 90° → (2, -1, 0); Y 90° → (0, -1, -2).
    let want = Vec3::new(10.0, -1.0, -2.0);
    assert!(
        mesh.positions.iter().any(|p| p.abs_diff_eq(want, 1e-5)),
        "{:?}",
        mesh.positions
    );
    // +Y normal → X 90° → +Z → Y 90° → +X, from the winding and the normals.
    assert!(mesh.face_normal(0).normalize().abs_diff_eq(Vec3::X, 1e-5));
    assert!(mesh
        .normals
        .as_ref()
        .unwrap()
        .iter()
        .all(|n| n.abs_diff_eq(Vec3::X, 1e-5)));
    // Non-uniform scale: normals by the inverse transpose, renormalised.
    let s = dir
        .load("[[object]]\nshape = \"sphere\"\nscale = [1, 4, 1]\nsegments = 8\nrings = 4\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
        let want = (*p * Vec3::new(1.0, 1.0 / 16.0, 1.0)).normalize();
        assert!(n.abs_diff_eq(want, 1e-5), "{n} vs {want}");
    }
}

#[test]
fn obj_materials_and_inline_replacement() {
    let dir = Dir::new("materials");
    dir.write(
        "m.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nusemtl red\nf 1//1 2//1 3//1\nusemtl glass\nf 2//1 4//1 3//1\nusemtl nothing\nf 1//1 2//1 4//1\n",
    );
    dir.write("m.mtl", "newmtl red\n  Kd 1 0 0\n  Ks 0.5\n  Ns 20\n  illum 2\n  Ka junk\nnewmtl glass\nKd 0.2 0.2 0.2\nTr 0.25\n");
    let s = dir.load("[[object]]\nobj = \"m.obj\"\n").unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangle_count(), 3);
    assert!(mesh.normals.is_some() && mesh.uvs.is_none());
    let mat = |t: usize| &s.materials[mesh.material_ids[t] as usize];
    assert_eq!((mat(0).name.as_str(), mat(0).albedo), ("red", Vec3::X));
    assert_eq!(
        (mat(0).specular, mat(0).shininess),
        (Vec3::splat(0.5), 20.0)
    );
    assert_eq!((mat(1).name.as_str(), mat(1).opacity), ("glass", 0.75));
    assert_eq!(
        mat(2).albedo,
        Vec3::splat(0.8),
        "unknown usemtl gets the default"
    );

    // An inline material replaces the MTL ones (which are then not read).
    std::fs::remove_file(dir.0.join("m.mtl")).unwrap();
    let s = dir
        .load("[[object]]\nobj = \"m.obj\"\nmaterial = { albedo = [0, 0, 1], opacity = 0.5 }\n")
        .unwrap();
    let mesh = &s.objects[0].mesh;
    for &id in &mesh.material_ids {
        let m = &s.materials[id as usize];
        assert_eq!(
            (m.albedo, m.opacity, m.name.as_str()),
            (Vec3::Z, 0.5, "inline")
        );
    }
}

#[test]
fn obj_partial_normals_degenerates_and_polygons() {
    let dir = Dir::new("partial");
    // One corner without a normal: normals dropped. A repeated-vertex
    // triangle and a collinear one are dropped; the pentagon gives 3.
    dir.write(
        "m.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nv 2 0 0\nvn 0 0 1\nf 1//1 2//1 3\nf 1 1 2\nf 1 2 6\nf 1 2 3 4 5\nl 1 2 3\n",
    );
    let s = dir.load("[[object]]\nobj = \"m.obj\"\n").unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangle_count(), 4);
    assert!(mesh.normals.is_none());
    assert_eq!(mesh.material_ids.len(), 4);
}

/// Writes a 2×2 RGB PNG: top row (0, 128), bottom row (255, 64), grey.
fn write_png(dir: &Dir, name: &str) -> PathBuf {
    let img = image::RgbImage::from_fn(2, 2, |x, y| {
        let v = [[0u8, 128], [255, 64]][y as usize][x as usize];
        image::Rgb([v, v, v])
    });
    let path = dir.0.join(name);
    img.save(&path).unwrap();
    path
}

fn srgb(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn textures_decode_srgb_and_follow_the_uv_convention() {
    let dir = Dir::new("textures");
    write_png(&dir, "t.png");
    let rgba = image::RgbaImage::from_fn(1, 1, |_, _| image::Rgba([255, 255, 255, 51]));
    rgba.save(dir.0.join("a.png")).unwrap();
    let s = dir
        .load(
            "[[object]]\nshape = \"quad\"\nmaterial = { albedo_texture = \"t.png\", opacity_texture = \"t.png\" }\n\
             [[object]]\nshape = \"box\"\nmaterial = { albedo_texture = \"./t.png\", opacity_texture = \"a.png\" }\n",
        )
        .unwrap();
    // t.png as colour and as opacity, a.png as opacity: three textures.
    assert_eq!(s.textures.len(), 3);
    let m = &s.materials[s.objects[0].mesh.material_ids[0] as usize];
    let colour = &s.textures[m.albedo_texture.unwrap()];
    let TextureData::Rgb(texels) = &colour.data else {
        panic!("colour texture not RGB")
    };
    assert_eq!((colour.width, colour.height), (2, 2));
    assert!(
        (texels[1].x - 0.21586).abs() < 1e-4,
        "sRGB 128 → {}",
        texels[1].x
    );
    assert_eq!(texels[1], Vec3::splat(srgb(128)));
    assert_eq!(texels[3], Vec3::splat(srgb(64)));
    // v = 0 is the bottom row; repeat outside [0, 1]; NaN/huge never panic.
    assert_eq!(colour.lookup_rgb(Vec2::new(0.25, 0.25)), Vec3::ONE);
    assert_eq!(
        colour.lookup_rgb(Vec2::new(0.75, 0.25)),
        Vec3::splat(srgb(64))
    );
    assert_eq!(colour.lookup_rgb(Vec2::new(0.25, 0.75)), Vec3::ZERO);
    assert_eq!(
        colour.lookup_rgb(Vec2::new(1.75, -0.25)),
        Vec3::splat(srgb(128))
    );
    assert_eq!(
        colour.lookup_rgb(Vec2::new(f32::NAN, f32::NAN)),
        colour.lookup_rgb(Vec2::new(0.0, 1.0))
    );
    for uv in [
        Vec2::splat(f32::INFINITY),
        Vec2::splat(-1e30),
        Vec2::new(1e9, f32::NEG_INFINITY),
    ] {
        let _ = (colour.lookup_rgb(uv), colour.lookup_scalar(uv));
    }
    // Light parametrisation: row t from the top, clamped.
    assert_eq!(colour.texel_st(0.0, 0.0), Vec3::ZERO);
    assert_eq!(colour.texel_st(1.0, 1.0), Vec3::splat(srgb(64)));
    assert_eq!(colour.texel_st(-3.0, 7.0), Vec3::ONE);
    let mean = (srgb(128) + 1.0 + srgb(64)) / 4.0;
    assert!((colour.mean_rgb() - Vec3::splat(mean)).length() < 1e-6);

    // Opacity is linear: luminance without alpha, else alpha.
    let opacity = &s.textures[m.opacity_texture.unwrap()];
    assert!((opacity.lookup_scalar(Vec2::new(0.75, 0.75)) - 128.0 / 255.0).abs() < 1e-6);
    let m = &s.materials[s.objects[1].mesh.material_ids[0] as usize];
    assert_eq!(
        m.albedo_texture,
        s.materials[s.objects[0].mesh.material_ids[0] as usize].albedo_texture
    );
    let alpha = &s.textures[m.opacity_texture.unwrap()];
    assert!((alpha.lookup_scalar(Vec2::new(0.5, 0.5)) - 0.2).abs() < 1e-6);
}

#[test]
fn rect_light_with_texture() {
    let dir = Dir::new("light-tex");
    write_png(&dir, "fire.png");
    let s = dir
        .load("[[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nu = [1, 0, 0]\nv = [0, 0, 1]\nradiance = 4\ntexture = \"fire.png\"\ntwo_sided = true\n")
        .unwrap();
    let l = &s.lights[0];
    assert_eq!(l.radiance, Vec3::splat(4.0));
    assert!(matches!(
        l.shape,
        LightShape::Rect {
            two_sided: true,
            ..
        }
    ));
    assert!(matches!(
        s.textures[l.texture.unwrap()].data,
        TextureData::Rgb(_)
    ));
}

// -------------------------------------------------- real models, scenes ----

/// The third-party models shipped in the repository.
fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models")
}

#[test]
fn stanford_bunny_loads() {
    let dir = Dir::new("bunny");
    let obj = models().join("stanford-bunny/stanford-bunny.obj");
    let s = dir
        .load(&format!("[[object]]\nobj = {:?}\n", obj.to_str().unwrap()))
        .unwrap();
    let mesh = &s.objects[0].mesh;
    // The bunny has no degenerate triangles.
    assert_eq!(mesh.triangle_count(), 69_451);
    assert!(mesh.normals.is_none() && mesh.uvs.is_none());
}

#[test]
fn crytek_sponza_subset_loads_with_alpha_masks() {
    let dir = Dir::new("sponza");
    let obj = models().join("crytek-sponza-alpha-subset/sponza_alpha_subset.obj");
    let s = dir
        .load(&format!("[[object]]\nobj = {:?}\n", obj.to_str().unwrap()))
        .unwrap();
    let mesh = &s.objects[0].mesh;
    // Per the models' README, and none of them is degenerate.
    assert_eq!(mesh.triangle_count(), 41_041);
    assert!(mesh.uvs.is_some());
    // Five map_Kd JPEGs and two map_d PNG masks.
    assert_eq!(s.textures.len(), 7);
    let masked: Vec<_> = s
        .materials
        .iter()
        .filter(|m| m.opacity_texture.is_some())
        .collect();
    assert_eq!(masked.len(), 2);
    for m in masked {
        let t = &s.textures[m.opacity_texture.unwrap()];
        let TextureData::Scalar(texels) = &t.data else {
            panic!("mask not scalar")
        };
        assert!(
            texels.iter().all(|&a| a == 0.0 || a == 1.0),
            "masks are binary"
        );
    }
}

#[test]
fn shipped_scenes_load() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let s = load_scene(&scenes.join("spheres.toml")).unwrap();
    assert_eq!(s.objects.len(), 82);
    assert_eq!(s.triangle_count(), 81 * 760 + 2);
    assert_eq!(s.lights.len(), 1);
    let (lo, hi) = s.bounds().unwrap();
    assert!(
        lo.abs_diff_eq(Vec3::new(-7.0, 0.0, -7.0), 1e-5)
            && hi.abs_diff_eq(Vec3::new(7.0, 1.85, 7.0), 1e-5)
    );
    for name in ["quad.toml", "bunny.toml"] {
        let s = load_scene(&scenes.join(name)).unwrap();
        assert!(s.triangle_count() > 0 && !s.lights.is_empty(), "{name}");
    }
}

// ------------------------------------------------- hostile input (#19) ----

/// Issue 19.4: every fixed-length array takes exactly its numbers: extra
/// elements (strings included), missing ones and non-numbers are errors
/// at the key's line that name the key.
#[test]
fn fixed_length_arrays_have_exactly_their_length() {
    let light = |key: &str, value: &str| {
        let base = [
            ("center", "[0, 3, 0]"),
            ("u", "[0.5, 0, 0]"),
            ("v", "[0, 0, 0.5]"),
            ("radiance", "[1, 1, 1]"),
        ];
        let mut s = String::from("[[light]]\ntype = \"rect\"\n");
        for (k, v) in base {
            let v = if k == key { value } else { v };
            s.push_str(&format!("{k} = {v}\n"));
        }
        s
    };
    let bad = [
        "[0.0, 5.0, 6.0, 99.0, \"x\"]",
        "[1, 2, 3, 4]",
        "[1, 2]",
        "[]",
        "[1, \"x\", 3]",
        "[1, true, 3]",
        "[1, [2], 3]",
    ];
    for (k, value) in bad.iter().enumerate() {
        // Camera keys: lines 2 (eye), 3 (target), 5 (up) of the file.
        for (key, line) in [("eye", 2), ("target", 3), ("up", 5)] {
            let dir = Dir::new(&format!("len-cam-{key}-{k}"));
            let mut lines = [
                "[camera]".to_string(),
                "eye = [0, 2, 5]".into(),
                "target = [0, 0, 0]".into(),
                "fov_y = 45".into(),
                "up = [0, 1, 0]".into(),
            ];
            lines[line - 1] = format!("{key} = {value}");
            let path = dir.write("scene.toml", lines.join("\n") + "\n");
            assert_error(load_scene(&path), &path, line, &format!("`{key}`"));
        }
        // Light keys, lines 8.. of the body (after the 5-line camera).
        for (key, line) in [("center", 8), ("u", 9), ("v", 10), ("radiance", 11)] {
            assert_scene_error(
                &format!("len-light-{key}-{k}"),
                &light(key, value),
                line,
                &format!("`{key}`"),
            );
        }
        for key in ["translate", "rotate", "scale"] {
            let body = format!("[[object]]\nshape = \"box\"\n{key} = {value}\n");
            assert_scene_error(&format!("len-obj-{key}-{k}"), &body, 8, &format!("`{key}`"));
        }
        for key in ["albedo", "specular"] {
            let body = format!("[[object]]\nshape = \"box\"\nmaterial = {{ {key} = {value} }}\n");
            assert_scene_error(&format!("len-mat-{key}-{k}"), &body, 8, &format!("`{key}`"));
        }
        for key in ["ambient", "background"] {
            let body = format!("[scene]\n{key} = {value}\n");
            assert_scene_error(
                &format!("len-scene-{key}-{k}"),
                &body,
                7,
                &format!("`{key}`"),
            );
        }
    }
    // The message says what was expected and what was found.
    assert_scene_error(
        "len-msg",
        "[[object]]\nshape = \"box\"\ntranslate = [0.0, 5.0, 6.0, 99.0, \"x\"]\n",
        8,
        "invalid length 5, expected an array of 3 numbers",
    );
    assert_scene_error(
        "len-msg-type",
        "[[object]]\nshape = \"box\"\ntranslate = [0.0, \"x\", 6.0]\n",
        8,
        "expected a number",
    );
    // `size` (2 or 3 numbers by shape) and integers where numbers go.
    assert_scene_error(
        "len-size-type",
        "[[object]]\nshape = \"box\"\nsize = [1, \"x\", 1]\n",
        8,
        "`size`",
    );
    let dir = Dir::new("len-ints");
    let s = dir
        .load("[[object]]\nshape = \"box\"\ntranslate = [1, -2, 3]\nscale = [1, 2, 3]\n")
        .unwrap();
    assert_eq!(s.objects.len(), 1);
}

/// Issue 19.6: values too large (or too small) for the supported range get
/// a message that says so, at their line: not "parallel", "zero area",
/// "must be finite" or "must not be zero".
#[test]
fn out_of_range_values_say_so() {
    let cam = |eye: &str| format!("[camera]\neye = {eye}\ntarget = [0, 0, 0]\nfov_y = 45\n");
    for (eye, needle) in [
        ("[1e38, 5, 6]", "beyond the supported range"),
        ("[3.5e38, 5, 6]", "out of range for f32 (max 3.4e38)"),
        ("[-3.5e38, 5, 6]", "out of range for f32"),
        ("[1.0000001e9, 5, 6]", "beyond the supported range"),
    ] {
        let dir = Dir::new("range-eye");
        let path = dir.write("scene.toml", cam(eye));
        assert_error(load_scene(&path), &path, 2, needle);
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("`camera.eye`") && !e.contains("parallel"), "{e}");
    }
    // The edge of the range loads.
    let dir = Dir::new("range-edge");
    let path = dir.write("scene.toml", cam("[1e9, -1e9, 5]"));
    load_scene(&path).unwrap();

    let rect = |u: &str| {
        format!("[[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nu = {u}\nv = [0, 0, 1]\nradiance = 1\n")
    };
    assert_scene_error(
        "range-u",
        &rect("[1e38, 0, 0]"),
        9,
        "beyond the supported range",
    );
    assert_scene_error(
        "range-u-tiny",
        &rect("[1e-20, 0, 0]"),
        9,
        "below the supported range",
    );
    let dir = Dir::new("range-u-msg");
    let e = dir.load(&rect("[1e38, 0, 0]")).unwrap_err().to_string();
    assert!(!e.contains("zero area"), "{e}");
    // Large but in range: a real light, not "zero area".
    Dir::new("range-u-big").load(&rect("[1e9, 0, 0]")).unwrap();

    let object = |extra: &str| format!("[[object]]\nshape = \"box\"\n{extra}\n");
    for (extra, needle) in [
        ("scale = 1e-20", "below the supported range"),
        ("scale = [1, 1e-20, 1]", "below the supported range"),
        ("scale = 3.5e38", "out of range for f32"),
        ("scale = 0", "must not be zero"),
        ("translate = [0, 1e38, 0]", "beyond the supported range"),
        ("rotate = [0, 4e38, 0]", "out of range for f32"),
        ("size = [1e-20, 1, 1]", "below the supported range"),
        ("size = [3.5e38, 1, 1]", "out of range for f32"),
    ] {
        let dir = Dir::new("range-obj");
        let r = dir.load(&object(extra));
        assert_error(r, &dir.0.join("scene.toml"), 8, needle);
        let e = dir.load(&object(extra)).unwrap_err().to_string();
        assert!(e.contains("object[0]"), "{e}");
    }
    // Each value in range, the transformed box not: said at its line.
    let dir = Dir::new("range-transformed");
    let r = dir.load("[[object]]\nshape = \"box\"\nsize = [1e5, 1, 1]\nscale = 1e5\n");
    assert_error(
        r,
        &dir.0.join("scene.toml"),
        7,
        "beyond the supported range",
    );
    // Sphere radius, sphere light radius, colours.
    assert_scene_error(
        "range-radius",
        "[[object]]\nshape = \"sphere\"\nradius = 1e-20\n",
        8,
        "below the supported range",
    );
    assert_scene_error(
        "range-light-radius",
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1e-20\nradiance = 1\n",
        9,
        "below the supported range",
    );
    assert_scene_error(
        "range-radiance",
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 1\nradiance = 1e38\n",
        10,
        "beyond the supported range",
    );
}

/// A scene given as TOML text is the scene its file gives (relative paths
/// resolved against the folder given), and a bad one is refused with the
/// file's message, naming the text instead of the file.
#[test]
fn a_scene_from_text_is_the_scene_from_its_file() {
    use penumbra::internal::scene::{load_scene, scene_from_toml, TOML_TEXT};
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["bunny", "fence", "tinted"] {
        let path = scenes.join(format!("{name}.toml"));
        let from_file = load_scene(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let mut from_text = scene_from_toml(&text, &scenes).unwrap();
        assert_eq!(from_text.path, std::path::Path::new(TOML_TEXT));
        from_text.path = from_file.path.clone();
        if from_file.name == name {
            from_text.name = from_file.name.clone();
        }
        assert_eq!(format!("{from_text:?}"), format!("{from_file:?}"), "{name}");
    }
    let bad = "[camera]\neye = [0.0, 1.0]\n";
    let dir = common::ScratchDir::new("scene_from_text");
    let file = dir.write("bad.toml", bad);
    let file_error = load_scene(&file).unwrap_err().to_string();
    let text_error = scene_from_toml(bad, &dir.0).unwrap_err().to_string();
    assert_eq!(
        text_error,
        file_error.replace(&file.display().to_string(), TOML_TEXT),
        "the same message, naming the text"
    );
    assert!(text_error.contains(":2"), "{text_error}");
}
