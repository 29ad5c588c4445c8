//! Scenes built in code (`SceneBuilder`): the same scene as its TOML text,
//! bit for bit; in-memory meshes as the same mesh from an OBJ file; and
//! the TOML path's checks and messages for bad input, naming the item and
//! key rather than a line of text the user never saw.

use crate::common;

use common::ScratchDir;
use penumbra::{
    render, scene_from_toml, CameraDesc, Error, LightDesc, MaterialDesc, MeshData, ObjectDesc,
    RenderOptions, Scene, SceneBuilder,
};
use std::path::Path;

/// Radiance bits of a small render (the exact technique, 16 samples).
fn radiance_bits(scene: &Scene) -> Vec<[u32; 3]> {
    let options = RenderOptions {
        samples: 16,
        width: Some(48),
        height: Some(36),
        ..RenderOptions::default()
    };
    let out = render(scene, &options).expect("render");
    out.radiance
        .iter()
        .map(|c| c.to_array().map(f32::to_bits))
        .collect()
}

/// Asserts that two scenes render to the same bits, and that the image is
/// not trivially uniform (so equality says something).
#[track_caller]
fn assert_same_render(a: &Scene, b: &Scene) {
    let (ra, rb) = (radiance_bits(a), radiance_bits(b));
    assert_eq!(ra.len(), 48 * 36);
    let first = ra[0];
    assert!(ra.iter().any(|&c| c != first), "uniform image");
    let differing = ra.iter().zip(&rb).filter(|(x, y)| x != y).count();
    assert_eq!(differing, 0, "{differing} pixels differ");
}

const CAMERA: CameraDesc = CameraDesc {
    eye: [0.0, 4.0, 6.0],
    target: [0.0, 0.5, 0.0],
    up: [0.0, 1.0, 0.0],
    fov_y: 45.0,
    width: 48,
    height: 36,
};

const CAMERA_TOML: &str = "[camera]
eye = [0.0, 4.0, 6.0]
target = [0.0, 0.5, 0.0]
fov_y = 45.0
width = 48
height = 36
";

/// A scene using every kind of item the builder has, but the in-memory mesh.
fn builder_scene() -> SceneBuilder {
    SceneBuilder::new()
        .name("built")
        .ambient([0.05, 0.04, 0.03])
        .background([0.1, 0.2, 0.3])
        .camera(CAMERA)
        .light(LightDesc::rect(
            [0.0, 4.0, 0.0],
            [0.6, 0.0, 0.0],
            [0.0, 0.0, 0.4],
            [9.0, 8.0, 7.0],
        ))
        .light(LightDesc::Rect {
            center: [2.0, 3.0, 1.0],
            u: [0.0, 0.3, 0.0],
            v: [0.0, 0.0, 0.3],
            radiance: [3.0, 3.0, 3.0],
            texture: None,
            two_sided: true,
        })
        .light(LightDesc::sphere(
            [-2.0, 3.0, -1.0],
            0.25,
            [20.0, 10.0, 5.0],
        ))
        .object(
            ObjectDesc::quad([8.0, 8.0])
                .named("ground")
                .material(MaterialDesc {
                    albedo: [0.7, 0.6, 0.5],
                    ..MaterialDesc::default()
                }),
        )
        .object(ObjectDesc::sphere(0.5).translate([0.5, 1.0, 0.0]))
        .object(ObjectDesc {
            geometry: penumbra::Geometry::Sphere {
                radius: 0.3,
                segments: 9,
                rings: 5,
            },
            ..ObjectDesc::sphere(1.0).translate([-1.0, 0.6, 0.5])
        })
        .object(
            ObjectDesc::cuboid([0.5, 1.0, 0.25])
                .translate([-0.8, 1.5, -0.5])
                .rotate([10.0, 30.0, -5.0])
                .scale([1.0, 0.5, 2.0])
                .material(MaterialDesc {
                    specular: [0.2, 0.2, 0.2],
                    shininess: 20.0,
                    ..MaterialDesc::default()
                }),
        )
        .object(
            ObjectDesc::quad([1.0, 1.5])
                .named("veil")
                .translate([0.0, 2.0, 0.5])
                .material(MaterialDesc {
                    opacity: 0.6,
                    ..MaterialDesc::default()
                })
                .shadows(true, false),
        )
        .object(
            ObjectDesc::sphere(0.2)
                .translate([1.5, 0.2, 1.0])
                .shadows(false, true),
        )
}

/// `builder_scene` as a scene file, written by hand with the defaults left
/// out where the contract has them.
const BUILDER_SCENE_TOML: &str = r#"
[scene]
name = "built"
ambient = [0.05, 0.04, 0.03]
background = [0.1, 0.2, 0.3]

[[light]]
type = "rect"
center = [0.0, 4.0, 0.0]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.4]
radiance = [9.0, 8.0, 7.0]

[[light]]
type = "rect"
center = [2.0, 3.0, 1.0]
u = [0.0, 0.3, 0.0]
v = [0.0, 0.0, 0.3]
radiance = 3
two_sided = true

[[light]]
type = "sphere"
center = [-2.0, 3.0, -1.0]
radius = 0.25
radiance = [20.0, 10.0, 5.0]

[[object]]
name = "ground"
shape = "quad"
size = [8.0, 8.0]
material = { albedo = [0.7, 0.6, 0.5] }

[[object]]
shape = "sphere"
radius = 0.5
translate = [0.5, 1.0, 0.0]

[[object]]
shape = "sphere"
radius = 0.3
segments = 9
rings = 5
translate = [-1.0, 0.6, 0.5]

[[object]]
shape = "box"
size = [0.5, 1.0, 0.25]
translate = [-0.8, 1.5, -0.5]
rotate = [10.0, 30.0, -5.0]
scale = [1.0, 0.5, 2.0]
material = { specular = [0.2, 0.2, 0.2], shininess = 20 }

[[object]]
name = "veil"
shape = "quad"
size = [1.0, 1.5]
translate = [0.0, 2.0, 0.5]
material = { opacity = 0.6 }
receive_shadows = false

[[object]]
shape = "sphere"
radius = 0.2
translate = [1.5, 0.2, 1.0]
cast_shadows = false
"#;

#[test]
fn built_scene_renders_as_its_toml_text() {
    let built = builder_scene().build().expect("build");
    let text = format!("{CAMERA_TOML}{BUILDER_SCENE_TOML}");
    let loaded = scene_from_toml(&text, Path::new(".")).expect("toml");
    assert_eq!(built.name, "built");
    assert_eq!(
        (built.camera, built.ambient),
        (loaded.camera, loaded.ambient)
    );
    assert_eq!(built.background, loaded.background);
    assert_eq!(built.lights, loaded.lights);
    assert_eq!(built.materials, loaded.materials);
    let names = |s: &Scene| s.objects.iter().map(|o| o.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(&built), names(&loaded));
    assert_eq!(names(&built)[1], "sphere#1");
    let flags = |s: &Scene| {
        (s.objects.iter())
            .map(|o| (o.cast_shadows, o.receive_shadows))
            .collect::<Vec<_>>()
    };
    assert_eq!(flags(&built), flags(&loaded));
    for (a, b) in built.objects.iter().zip(&loaded.objects) {
        assert_eq!(a.mesh.positions, b.mesh.positions, "{}", a.name);
        assert_eq!(a.mesh.triangles, b.mesh.triangles, "{}", a.name);
        assert_eq!(a.mesh.material_ids, b.mesh.material_ids, "{}", a.name);
    }
    assert_same_render(&built, &loaded);
}

/// A small tent-shaped occluder with one degenerate triangle (dropped by
/// both paths), normals and uvs; vertices appear in the faces in index
/// order so that the OBJ loader keeps their order.
fn tent() -> MeshData {
    let positions = vec![
        [-0.6, 0.0, -0.4],
        [0.6, 0.0, -0.4],
        [0.0, 0.5, 0.0],
        [0.6, 0.0, 0.4],
        [-0.6, 0.0, 0.4],
        [0.0, 0.5, 0.0],
    ];
    let normals = vec![
        [0.0, 0.6, -0.8],
        [0.0, 0.6, -0.8],
        [0.0, 1.0, 0.0],
        [0.0, 0.6, 0.8],
        [0.0, 0.6, 0.8],
        [0.0, 1.0, 0.0],
    ];
    let uvs = vec![
        [0.0, 0.0],
        [1.0, 0.0],
        [0.5, 1.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [0.5, 0.5],
    ];
    MeshData {
        positions,
        triangles: vec![[0, 1, 2], [3, 4, 5], [2, 5, 2]],
        normals: Some(normals),
        uvs: Some(uvs),
    }
}

/// `mesh` as OBJ text, every face corner `v/vt/vn` with one index.
fn to_obj(mesh: &MeshData) -> String {
    let mut s = String::new();
    for p in &mesh.positions {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for uv in mesh.uvs.iter().flatten() {
        s += &format!("vt {} {}\n", uv[0], uv[1]);
    }
    for n in mesh.normals.iter().flatten() {
        s += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
    }
    let corner = |i: u32| match (&mesh.uvs, &mesh.normals) {
        (Some(_), Some(_)) => format!("{0}/{0}/{0}", i + 1),
        _ => format!("{}", i + 1),
    };
    for t in &mesh.triangles {
        s += &format!("f {} {} {}\n", corner(t[0]), corner(t[1]), corner(t[2]));
    }
    s
}

/// The builder scene around one occluder object.
fn around(occluder: ObjectDesc, dir: &Path) -> SceneBuilder {
    SceneBuilder::new()
        .base_dir(dir)
        .camera(CAMERA)
        .light(LightDesc::rect(
            [0.0, 4.0, 0.0],
            [0.6, 0.0, 0.0],
            [0.0, 0.0, 0.4],
            [9.0, 9.0, 9.0],
        ))
        .object(ObjectDesc::quad([8.0, 8.0]))
        .object(occluder)
}

#[test]
fn in_memory_mesh_renders_as_the_same_obj_file() {
    let dir = ScratchDir::new("builder-mesh");
    for mesh in [tent(), MeshData::new(tent().positions, tent().triangles)] {
        dir.write("tent.obj", to_obj(&mesh));
        let place = |o: ObjectDesc| {
            o.named("tent")
                .translate([0.2, 1.2, 0.1])
                .rotate([0.0, 25.0, 10.0])
                .scale([1.5, 1.0, -1.0])
        };
        let from_memory = around(place(ObjectDesc::mesh(mesh.clone())), &dir.0)
            .build()
            .expect("in-memory mesh");
        let from_file = around(place(ObjectDesc::obj("tent.obj")), &dir.0)
            .build()
            .expect("obj");
        let (a, b) = (&from_memory.objects[1].mesh, &from_file.objects[1].mesh);
        assert_eq!(a.triangle_count(), 2, "the degenerate triangle is dropped");
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.normals, b.normals);
        assert_eq!(a.uvs, b.uvs);
        assert_same_render(&from_memory, &from_file);
    }
}

/// The message of an error, whatever its kind.
fn message(e: &Error) -> &str {
    match e {
        Error::File { message, .. } | Error::Parameter { message, .. } => message,
        _ => panic!("unexpected error {e}"),
    }
}

/// The builder's error: a parameter error named `name`, its message
/// containing `needle`.
#[track_caller]
fn built_error(b: SceneBuilder, name: &str, needle: &str) -> Error {
    let e = b.build().expect_err("bad input must fail");
    match &e {
        Error::Parameter { name: n, message } => {
            assert_eq!(n, name, "message: {message}");
            assert!(message.contains(needle), "`{message}` lacks `{needle}`");
        }
        other => panic!("expected a parameter error, got {other:?}"),
    }
    e
}

/// Asserts that the builder's error and the scene file's error for the same
/// mistake have the same message; the file's names the line.
#[track_caller]
fn same_as_toml(built: &Error, toml_body: &str) {
    let text = format!("{CAMERA_TOML}{toml_body}");
    let e = scene_from_toml(&text, Path::new(".")).expect_err("bad TOML must fail");
    assert!(matches!(e, Error::File { line: Some(_), .. }), "{e:?}");
    assert_eq!(message(built), message(&e));
}

fn with_camera() -> SceneBuilder {
    SceneBuilder::new().camera(CAMERA)
}

#[test]
fn bad_values_fail_as_in_a_scene_file() {
    let e = built_error(
        with_camera().object(ObjectDesc::sphere(-0.5).named("ball")),
        "object \"ball\".radius",
        "`object[0].radius` must be positive",
    );
    same_as_toml(&e, "[[object]]\nshape = \"sphere\"\nradius = -0.5\n");

    let e = built_error(
        with_camera().light(LightDesc::sphere([0.0; 3], -1.0, [1.0; 3])),
        "light[0].radius",
        "sphere light `radius` must be positive",
    );
    same_as_toml(
        &e,
        "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\nradiance = 1\n",
    );

    let e = built_error(
        with_camera().object(ObjectDesc::cuboid([1.0; 3]).translate([f64::NAN, 0.0, 0.0])),
        "object[0].translate",
        "`object[0].translate` must be finite",
    );
    same_as_toml(
        &e,
        "[[object]]\nshape = \"box\"\ntranslate = [nan, 0.0, 0.0]\n",
    );

    let e = built_error(
        with_camera().light(LightDesc::rect(
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0; 3],
        )),
        "light[0].v",
        "rect light has zero area",
    );
    same_as_toml(
        &e,
        "[[light]]\ntype = \"rect\"\ncenter = [0, 0, 0]\nu = [1, 0, 0]\nv = [2, 0, 0]\n\
         radiance = 1\n",
    );

    let e = built_error(
        with_camera().object(ObjectDesc::quad([1.0, 0.0])),
        "object[0].size",
        "`object[0].size` must be 2 positive numbers",
    );
    same_as_toml(&e, "[[object]]\nshape = \"quad\"\nsize = [1, 0]\n");

    let e = built_error(
        with_camera().object(ObjectDesc::sphere(1.0).material(MaterialDesc {
            opacity: 1.5,
            ..MaterialDesc::default()
        })),
        "object[0].material",
        "`object[0].material.opacity` = 1.5 must be in [0, 1]",
    );
    same_as_toml(
        &e,
        "[[object]]\nshape = \"sphere\"\nmaterial = { opacity = 1.5 }\n",
    );

    let e = built_error(
        with_camera().ambient([-1.0, 0.0, 0.0]),
        "scene.ambient",
        "`scene.ambient` must not be negative",
    );
    same_as_toml(&e, "[scene]\nambient = [-1, 0, 0]\n");
}

#[test]
fn names_are_taken_as_given() {
    let odd = "two\nlines \"quoted\" = [[object]] \u{e9}";
    let scene = with_camera()
        .name(odd)
        .object(ObjectDesc::sphere(1.0).named(odd))
        .build()
        .expect("odd names");
    assert_eq!(
        (scene.name.as_str(), scene.objects[0].name.as_str()),
        (odd, odd)
    );
    let e = built_error(
        with_camera().object(ObjectDesc::sphere(0.0).named(odd)),
        &format!("object {odd:?}.radius"),
        "`object[0].radius` must be positive",
    );
    assert!(!e.to_string().contains(penumbra::BUILT_SCENE), "{e}");
}

#[test]
fn camera_errors_fail_as_in_a_scene_file() {
    let no_camera = SceneBuilder::new().object(ObjectDesc::sphere(1.0));
    let e = built_error(no_camera, "camera", "missing field `camera`");
    let toml = scene_from_toml("[[object]]\nshape = \"sphere\"\n", Path::new("."));
    assert_eq!(message(&e), message(&toml.expect_err("no camera")));

    let bad = |c: CameraDesc| SceneBuilder::new().camera(c);
    let e = built_error(
        bad(CameraDesc {
            fov_y: 180.0,
            ..CAMERA
        }),
        "camera.fov_y",
        "`camera.fov_y` = 180 must be in (0, 180) degrees",
    );
    let text = CAMERA_TOML.replace("fov_y = 45.0", "fov_y = 180.0");
    let toml = scene_from_toml(&text, Path::new(".")).expect_err("fov");
    assert_eq!(message(&e), message(&toml));

    built_error(
        bad(CAMERA.size(0, 36)),
        "camera.width",
        "`camera.width` = 0 is outside 1..=",
    );
    built_error(
        bad(CAMERA.up([0.0, 0.0, 0.0])),
        "camera.up",
        "must not be parallel to the view direction",
    );
}

#[test]
fn bad_meshes_fail_with_the_key_and_index() {
    let mesh = |m: MeshData| with_camera().object(ObjectDesc::mesh(m));
    let mut m = tent();
    m.positions[3][1] = f32::NAN;
    built_error(
        mesh(m),
        "object[0].mesh",
        "`object[0].positions[3]` must be finite",
    );

    let mut m = tent();
    m.uvs.as_mut().unwrap()[5][0] = f32::INFINITY;
    built_error(
        mesh(m),
        "object[0].mesh",
        "`object[0].uvs[5]` must be finite",
    );

    let mut m = tent();
    m.triangles[1][2] = 6;
    built_error(
        mesh(m),
        "object[0].mesh",
        "`object[0].triangles[1]`: vertex index 6 out of range: the mesh has 6 positions",
    );

    let mut m = tent();
    m.normals.as_mut().unwrap().pop();
    built_error(
        mesh(m),
        "object[0].mesh",
        "`object[0].normals` has 5 entries for 6 positions",
    );

    built_error(
        mesh(MeshData::new(tent().positions, vec![])),
        "object[0].mesh",
        "`object[0].triangles` is empty",
    );

    // Zero normals are replaced by the face's, as in an OBJ file.
    let mut m = tent();
    m.normals.as_mut().unwrap()[0] = [0.0; 3];
    let scene = mesh(m).build().expect("zero normal");
    let normals = scene.objects[0].mesh.normals.as_ref().unwrap();
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-6));
}

#[test]
fn mesh_beyond_the_range_fails_as_the_same_obj() {
    let dir = ScratchDir::new("builder-range");
    let m = MeshData::new(
        vec![[0.0; 3], [1e5, 0.0, 0.0], [0.0, 1e5, 0.0]],
        vec![[0, 1, 2]],
    );
    dir.write("far.obj", to_obj(&m));
    let scaled = |o: ObjectDesc| o.named("far").scale([1e5; 3]);
    let memory = around(scaled(ObjectDesc::mesh(m)), &dir.0).build();
    let file = around(scaled(ObjectDesc::obj("far.obj")), &dir.0).build();
    let (memory, file) = (memory.expect_err("memory"), file.expect_err("file"));
    assert_eq!(message(&memory), message(&file));
    assert!(
        message(&memory).contains("beyond the supported range"),
        "{memory}"
    );
}

#[test]
fn obj_errors_name_the_obj_file_or_the_object() {
    let dir = ScratchDir::new("builder-obj");
    // A missing file: there is no line to cite, the object is named.
    let e = built_error(
        around(ObjectDesc::obj("missing.obj"), &dir.0),
        "object[1].obj",
        "cannot read OBJ",
    );
    assert!(!e.to_string().contains(penumbra::BUILT_SCENE), "{e}");
    // An error inside the OBJ file names that file and line.
    let obj = dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    let e = around(ObjectDesc::obj("bad.obj"), &dir.0)
        .build()
        .expect_err("bad obj");
    match e {
        Error::File { path, line, .. } => assert_eq!((path, line), (obj, Some(4))),
        other => panic!("expected the OBJ's error, got {other:?}"),
    }
}

#[test]
fn textures_resolve_against_the_base_dir_as_in_a_scene_file() {
    let dir = ScratchDir::new("builder-textures");
    std::fs::create_dir_all(dir.0.join("tex")).unwrap();
    let checker = image::RgbaImage::from_fn(4, 4, |x, y| match (x + y) % 2 {
        0 => image::Rgba([255, 200, 50, 255]),
        _ => image::Rgba([20, 40, 220, 0]),
    });
    checker.save(dir.0.join("tex/checker.png")).unwrap();
    let textured = |light_texture: &str| {
        SceneBuilder::new()
            .base_dir(&dir.0)
            .camera(CAMERA)
            .light(LightDesc::Rect {
                center: [0.0, 4.0, 0.0],
                u: [0.8, 0.0, 0.0],
                v: [0.0, 0.0, 0.8],
                radiance: [9.0; 3],
                texture: Some(light_texture.into()),
                two_sided: false,
            })
            .object(ObjectDesc::quad([8.0, 8.0]).material(MaterialDesc {
                albedo_texture: Some("tex/checker.png".into()),
                ..MaterialDesc::default()
            }))
            .object(
                ObjectDesc::quad([2.0, 2.0])
                    .translate([0.0, 1.5, 0.0])
                    .material(MaterialDesc {
                        opacity_texture: Some("tex/checker.png".into()),
                        ..MaterialDesc::default()
                    }),
            )
    };
    let body = |light_texture: &str| {
        format!(
            "{CAMERA_TOML}[[light]]\ntype = \"rect\"\ncenter = [0, 4, 0]\nu = [0.8, 0, 0]\n\
             v = [0, 0, 0.8]\nradiance = 9\ntexture = \"{light_texture}\"\n\
             [[object]]\nshape = \"quad\"\nsize = [8, 8]\n\
             material = {{ albedo_texture = \"tex/checker.png\" }}\n\
             [[object]]\nshape = \"quad\"\nsize = [2, 2]\ntranslate = [0, 1.5, 0]\n\
             material = {{ opacity_texture = \"tex/checker.png\" }}\n"
        )
    };
    let built = textured("tex/checker.png").build().expect("build");
    let loaded = scene_from_toml(&body("tex/checker.png"), &dir.0).expect("toml");
    assert_eq!(
        built.textures.len(),
        2,
        "one colour and one opacity texture"
    );
    assert_eq!(built.lights, loaded.lights);
    assert_eq!(built.materials, loaded.materials);
    assert_same_render(&built, &loaded);

    let e = built_error(textured("tex/none.png"), "light[0].texture", "none.png");
    let toml = scene_from_toml(&body("tex/none.png"), &dir.0).expect_err("missing texture");
    assert_eq!(message(&e), message(&toml));
}
