//! What penumbra reads and what it refuses to read: only regular files
//! (a FIFO would block, `/dev/zero` never ends), at most the input size
//! limit, and meshes only as OBJ or PLY (other mesh formats would load as
//! nothing). Every input file goes through `penumbra::internal::scene::input::read`:
//! scenes, OBJ and MTL files, textures, `diff` images and tile parts.

use crate::common;

use penumbra::internal::scene::{input, load_scene};
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::ScratchDir as Dir;

/// This file's own uses of a scratch directory.
trait InputsDir {
    fn fifo(&self, name: &str) -> PathBuf;
    fn scene(&self, object: &str) -> PathBuf;
}

impl InputsDir for Dir {
    /// A FIFO named `name` (nobody ever writes to it).
    fn fifo(&self, name: &str) -> PathBuf {
        let path = self.0.join(name);
        let ok = std::process::Command::new("mkfifo")
            .arg(&path)
            .status()
            .expect("run mkfifo")
            .success();
        assert!(ok, "mkfifo {}", path.display());
        path
    }

    /// A scene with one light and `object` (the body of an `[[object]]`).
    fn scene(&self, object: &str) -> PathBuf {
        self.write(
            "scene.toml",
            format!(
                "[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45.0\n\
                 width = 16\nheight = 16\n\
                 [[light]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0.5\nradiance = 1\n\
                 [[object]]\n{object}\n"
            ),
        )
    }
}

/// Runs `f` on another thread and returns its result, or fails the test
/// if it has not returned within 20 s (a read that blocks on a FIFO).
fn within_time<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(20))
        .unwrap_or_else(|_| panic!("{what}: still blocked after 20 s"))
}

/// The scene's load error message, which must come in time.
fn load_error(what: &str, scene: PathBuf) -> String {
    within_time(what, move || match load_scene(&scene) {
        Ok(_) => panic!("{}: loads", scene.display()),
        Err(e) => e.to_string(),
    })
}

const QUAD_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

#[test]
fn fifos_are_refused_not_waited_on() {
    let dir = Dir::new("fifo");
    let fifo = dir.fifo("fifo");
    let fifo_name = fifo.to_str().unwrap().to_string();
    let expect = |what: &str, msg: &str, names: &str| {
        assert!(
            msg.contains("FIFO") && msg.contains("only regular files") && msg.contains(names),
            "{what}: {msg}"
        );
    };
    // The scene itself.
    expect("scene", &load_error("scene", fifo.clone()), &fifo_name);
    // An OBJ, at the scene line naming it.
    let scene = dir.scene("obj = \"fifo\"");
    let msg = load_error("obj", scene);
    expect("obj", &msg, "scene.toml:13: cannot read OBJ");
    // An MTL file of an OBJ.
    dir.write("m.obj", format!("mtllib fifo\n{QUAD_OBJ}"));
    let msg = load_error("mtl", dir.scene("obj = \"m.obj\""));
    expect("mtl", &msg, "m.obj:1: cannot read MTL");
    // A texture, of a material and of a light.
    let scene = dir.scene("shape = \"quad\"\nmaterial = { albedo_texture = \"fifo\" }");
    expect("texture", &load_error("texture", scene), "texture `");
    dir.write(
        "light.toml",
        "[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45.0\n\
         [[light]]\ntype = \"rect\"\ncenter = [0, 3, 0]\nu = [1, 0, 0]\nv = [0, 0, 1]\n\
         radiance = 1\ntexture = \"fifo\"\n",
    );
    let msg = load_error("light texture", dir.0.join("light.toml"));
    expect("light texture", &msg, "texture `");
    // `diff` inputs and tile parts.
    let f = fifo.clone();
    let msg = within_time("image", move || {
        penumbra::internal::output::read_image(&f)
            .unwrap_err()
            .to_string()
    });
    expect("diff input", &msg, &fifo_name);
    let f = fifo.clone();
    let msg = within_time("tile part", move || {
        penumbra::internal::cluster::tiles::read_part(&f)
            .expect_err("a FIFO is no part")
            .to_string()
    });
    expect("tile part", &msg, &fifo_name);
}

#[test]
fn devices_and_directories_are_refused_before_reading() {
    let dir = Dir::new("devzero");
    let start = std::time::Instant::now();
    let msg = load_error("scene", PathBuf::from("/dev/zero"));
    assert!(msg.contains("/dev/zero: a character device"), "{msg}");
    let msg = load_error("obj", dir.scene("obj = \"/dev/zero\""));
    assert!(
        msg.contains("cannot read OBJ `/dev/zero`: a character device"),
        "{msg}"
    );
    let scene = dir.scene("shape = \"quad\"\nmaterial = { albedo_texture = \"/dev/zero\" }");
    let msg = load_error("texture", scene);
    assert!(msg.contains("character device"), "{msg}");
    let msg = penumbra::internal::output::read_image(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("character device"), "{msg}");
    let msg = load_error("directory", dir.0.clone());
    assert!(msg.contains("a directory"), "{msg}");
    // Refused from the metadata, without reading a byte.
    assert!(start.elapsed() < Duration::from_secs(10));
}

#[test]
fn files_over_the_limit_are_refused() {
    let dir = Dir::new("limit");
    let file = dir.write("big", vec![b'#'; 1000]);
    assert_eq!(input::read_limited(&file, 1000).unwrap().len(), 1000);
    let msg = input::read_limited(&file, 999).unwrap_err().to_string();
    assert!(
        msg.contains("1000 bytes is more than the input limit"),
        "{msg}"
    );
    assert_eq!(
        input::MAX_INPUT_BYTES,
        4 << 30,
        "docs/scene-format.md says 4 GiB"
    );
}

#[test]
fn other_mesh_formats_are_refused_by_extension_and_content() {
    let dir = Dir::new("formats");
    let ply_ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                     property float y\nproperty float z\nelement face 1\n\
                     property list uchar int vertex_indices\nend_header\n\
                     0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let mut ply_binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
                           property float x\nend_header\n"
        .to_vec();
    ply_binary.extend([0u8, 0x80, 0xff, 0xfe, 1, 2, 3, 4, 5, 6, 7, 8]);
    let stl_ascii = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n\
                     vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    // An 80-byte header, one triangle (normal, 3 vertices, attribute).
    let mut stl_binary = vec![0u8; 80];
    stl_binary.extend(1u32.to_le_bytes());
    for x in [
        0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
    ] {
        stl_binary.extend(x.to_le_bytes());
    }
    stl_binary.extend([0u8, 0]);
    let off = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let gltf = "{\n  \"asset\": {\"version\": \"2.0\"},\n  \"meshes\": []\n}\n";
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(20u32.to_le_bytes());
    glb.extend([0xffu8; 8]);
    let cases: [(&str, &[u8], &str); 7] = [
        ("ply", ply_ascii.as_bytes(), "PLY"),
        ("ply", &ply_binary, "PLY"),
        ("stl", stl_ascii.as_bytes(), "STL"),
        ("stl", &stl_binary, "binary STL"),
        ("off", off.as_bytes(), "OFF"),
        ("gltf", gltf.as_bytes(), "glTF"),
        ("glb", &glb, "binary glTF"),
    ];
    for (ext, bytes, format) in cases {
        // By extension, and by content alone (named `.obj`); a file named
        // `.ply`, `.gltf` or `.glb` goes to its own reader (below).
        for name in [format!("mesh.{ext}"), format!("mesh-{ext}.obj")] {
            if [".ply", ".gltf", ".glb"].iter().any(|e| name.ends_with(e)) {
                continue;
            }
            dir.write(&name, bytes);
            let msg = load_error(&name, dir.scene(&format!("obj = \"{name}\"")));
            let by_content = name.ends_with(".obj");
            let want = if by_content || ext != "stl" {
                format
            } else {
                "STL"
            };
            assert!(
                msg.contains(&format!("scene.toml:13: `{}", dir.0.display()))
                    && msg.contains(&format!("{name}` is a"))
                    && msg.contains(want)
                    && msg.contains("penumbra reads meshes as Wavefront OBJ"),
                "{name}: {msg}"
            );
            if format == "PLY" {
                assert!(msg.contains("PLY is read from files named `.ply`"), "{msg}");
            }
            if format.contains("glTF") {
                assert!(
                    msg.contains("glTF is read from files named `.gltf` or `.glb`"),
                    "{msg}"
                );
            }
        }
    }
    // Named `.ply`, the PLY reader reads it: the well-formed file loads,
    // the truncated binary one is refused naming the element.
    dir.write("mesh.ply", ply_ascii.as_bytes());
    let scene = load_scene(&dir.scene("obj = \"mesh.ply\"")).expect("a PLY named .ply loads");
    assert_eq!(scene.objects[0].mesh.triangle_count(), 1);
    dir.write("broken.ply", &ply_binary);
    let msg = load_error("broken.ply", dir.scene("obj = \"broken.ply\""));
    assert!(
        msg.contains("broken.ply") && msg.contains("`vertex`"),
        "{msg}"
    );
    // Named `.gltf` and `.glb`, the glTF reader reads them: a file without
    // a triangle and a GLB with a bad chunk are refused naming the file.
    dir.write("mesh.gltf", gltf.as_bytes());
    let msg = load_error("mesh.gltf", dir.scene("obj = \"mesh.gltf\""));
    assert!(msg.contains("mesh.gltf"), "{msg}");
    dir.write("mesh.glb", &glb);
    let msg = load_error("mesh.glb", dir.scene("obj = \"mesh.glb\""));
    assert!(msg.contains("mesh.glb") && msg.contains("GLB"), "{msg}");
    // An OBJ is still an OBJ, whatever its extension.
    dir.write("quad.txt", QUAD_OBJ);
    let scene = load_scene(&dir.scene("obj = \"quad.txt\"")).expect("an OBJ named .txt loads");
    assert_eq!(scene.objects[0].mesh.triangle_count(), 2);
}

#[test]
fn an_obj_without_faces_is_refused() {
    let dir = Dir::new("nofaces");
    for (name, body) in [
        ("points.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\n"),
        ("lines.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\n"),
        ("empty.obj", ""),
    ] {
        dir.write(name, body);
        let msg = load_error(name, dir.scene(&format!("obj = \"{name}\"")));
        // Named at the scene's line, with the OBJ's name.
        assert!(msg.contains("scene.toml:"), "{name}: {msg}");
        assert!(
            msg.contains(&format!("{name}` has no faces")),
            "{name}: {msg}"
        );
    }
}
