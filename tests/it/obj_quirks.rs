//! OBJ and MTL files as exporters write them: each quirk of real files
//! reproduced in a small file written to a scratch directory, loaded
//! through the public API. What is accepted is listed in
//! docs/scene-format.md ("OBJ and MTL files in the wild").

use glam::Vec3;
use penumbra::internal::scene::{load_scene, Scene, TextureData};
use penumbra::Error;
use std::path::{Path, PathBuf};

/// A scratch directory, unique per test, removed when dropped.
struct Dir(PathBuf);

impl Dir {
    fn new(test: &str) -> Dir {
        let dir = std::env::temp_dir().join(format!("penumbra-objq-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Dir(dir)
    }

    fn write(&self, name: &str, content: impl AsRef<[u8]>) -> PathBuf {
        let path = self.0.join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, content).unwrap();
        path
    }

    /// Loads a scene with one object, the OBJ file `obj`.
    fn load(&self, obj: &str) -> penumbra::Result<Scene> {
        let scene = format!(
            "[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45.0\nwidth = 16\n\
             [[object]]\nobj = {obj:?}\n"
        );
        load_scene(&self.write("scene.toml", scene))
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A 2×2 RGBA PNG: opaque red, except texel (1, 1) transparent.
fn png() -> Vec<u8> {
    let mut img = image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255]));
    img.put_pixel(1, 1, image::Rgba([0, 0, 0, 0]));
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    bytes
}

/// One unit quad in z = 0 as two triangles, with uvs, using `material`.
fn quad_obj(mtllib: &str, material: &str) -> String {
    format!(
        "mtllib {mtllib}\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl {material}\nf 1/1 2/2 3/3 4/4\n"
    )
}

/// A zero and a NaN normal among good ones: the model loads, the corners
/// that used them get their face's geometric normal, good corners keep
/// theirs, a vertex shared by two faces with different normals is split,
/// and nothing non-finite is left.
#[test]
fn unusable_normals_fall_back_to_the_face_normal() {
    let dir = Dir::new("normals");
    // Triangle 0 in z = 0 (geometric normal +z), triangle 1 in x = 0
    // (+x), triangle 2 in z = 0 wound the other way (-z): all three share
    // vertex 1 through the zero normal (vn 2).
    dir.write(
        "m.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
         vn 0 0.6 0.8\nvn 0 0 0\nvn nan 0 1\nvn 1e-30 0 0\n\
         f 1//2 2//1 3//1\nf 1//2 3//3 4//3\nf 1//2 3//4 2//4\n",
    );
    let s = dir.load("m.obj").unwrap();
    let mesh = &s.objects[0].mesh;
    let normals = mesh.normals.as_ref().expect("every corner has a vn");
    assert!(normals
        .iter()
        .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-6));
    assert_eq!(mesh.triangle_count(), 3);
    let corner = |t: usize, k: usize| normals[mesh.triangles[t][k] as usize];
    let geometric = |t: usize| {
        let [a, b, c] = mesh.corners(t);
        (b - a).cross(c - a).normalize()
    };
    // Triangle 0: corner 0 was vn 2 (zero), the others keep vn 1.
    assert!(corner(0, 0).abs_diff_eq(geometric(0), 1e-6));
    assert!(geometric(0).abs_diff_eq(Vec3::Z, 1e-6));
    assert!(corner(0, 1).abs_diff_eq(Vec3::new(0.0, 0.6, 0.8), 1e-6));
    // Triangle 1 lies in x = 0: every corner was unusable (zero, NaN).
    for k in 0..3 {
        assert!(
            corner(1, k).abs_diff_eq(geometric(1), 1e-6),
            "triangle 1 corner {k}"
        );
    }
    assert!(geometric(1).abs_diff_eq(Vec3::X, 1e-6));
    // Triangle 2 (1e-30 normals underflow: unusable too) needs -z at the
    // vertex triangle 0 gave +z (and triangle 1 +x): each got a copy.
    for k in 0..3 {
        assert!(
            corner(2, k).abs_diff_eq(-Vec3::Z, 1e-6),
            "triangle 2 corner {k}"
        );
    }
    let shared: Vec<u32> = (0..3).map(|t| mesh.triangles[t][0]).collect();
    assert!(shared[0] != shared[1] && shared[1] != shared[2] && shared[0] != shared[2]);
    assert!(shared
        .iter()
        .all(|&v| mesh.positions[v as usize] == Vec3::ZERO));
}

/// A UTF-8 byte-order mark before the first statement of an OBJ and of an
/// MTL: neither the first `v` nor the first `newmtl` is lost.
#[test]
fn byte_order_marks_keep_the_first_statement() {
    let dir = Dir::new("bom");
    dir.write(
        "m.obj",
        "\u{feff}v 0 0 0\nv 1 0 0\nv 0 1 0\nmtllib m.mtl\nusemtl red\nf 1 2 3\n",
    );
    dir.write("m.mtl", "\u{feff}newmtl red\nKd 1 0 0\n");
    let s = dir.load("m.obj").unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.positions.len(), 3);
    assert_eq!(mesh.positions[0], Vec3::ZERO);
    let m = &s.materials[mesh.material_ids[0] as usize];
    assert_eq!(
        (m.name.as_str(), m.albedo),
        ("red", Vec3::new(1.0, 0.0, 0.0))
    );
}

/// A face whose normal index is defined only later, in a file with an
/// `mtllib` (issue: tobj reports it without a line): the error names the
/// OBJ file and the face's line. The same for uvs and positions.
#[test]
fn forward_references_name_the_file_and_line() {
    let cases = [
        (
            "normal",
            "f 1//2 2//2 3//2\nvn 0 0 1\nvn 0 0 1\n",
            "normals",
        ),
        (
            "uv",
            "f 1/2 2/2 3/2\nvt 0 0\nvt 1 1\n",
            "texture coordinates",
        ),
        ("position", "f 1 2 4\nv 0 0 1\n", "vertices"),
    ];
    for (name, tail, kind) in cases {
        let dir = Dir::new(&format!("fwd-{name}"));
        dir.write("m.mtl", "newmtl a\nKd 1 1 1\n");
        let obj = dir.write(
            "m.obj",
            format!("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\n{tail}"),
        );
        match dir.load("m.obj") {
            Err(Error::File {
                path,
                line,
                message,
            }) => {
                assert_eq!(
                    (path.as_path(), line),
                    (obj.as_path(), Some(6)),
                    "{name}: {message}"
                );
                assert!(message.contains(kind), "{name}: {message}");
            }
            other => panic!("{name}: expected an error at m.obj:6, got {other:?}"),
        }
    }
}

/// `s`, `g`, `o`, `l`, `p` lines, free-form statements and comments: a
/// model written with all of them has exactly its faces' triangles.
#[test]
fn grouping_smoothing_lines_and_points_are_skipped() {
    let dir = Dir::new("groups");
    dir.write(
        "m.obj",
        "# exporter header\no\ng\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
         o part one\ng walls floor\ns 1\nf 1 2 3\ns off\ng\nl 1 2 3 4\np 1 2\n\
         vp 0.5 0.5\ncstype bezier\nmg 1\ns 2\nf 2 4 3\nf 1 2\n",
    );
    let s = dir.load("m.obj").unwrap();
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangles.len(), 2);
    let mut tris: Vec<[Vec3; 3]> = (0..2).map(|t| mesh.corners(t)).collect();
    tris.sort_by(|a, b| a[0].x.total_cmp(&b[0].x));
    assert_eq!(tris[0], [Vec3::ZERO, Vec3::X, Vec3::Y]);
    assert_eq!(tris[1], [Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
}

/// Vertex colours on some vertices only (as some scanners write them): the
/// colours are dropped, the positions kept exactly as written.
#[test]
fn vertex_colours_on_some_vertices_only() {
    let dir = Dir::new("colours");
    dir.write(
        "m.obj",
        "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0.5 0.5 0.5\nv 1.1 1.3 0\nf 1 2 3\nf 2 4 3\n",
    );
    let s = dir.load("m.obj").expect("mixed vertex colours load");
    let mesh = &s.objects[0].mesh;
    assert_eq!(mesh.triangles.len(), 2);
    let mut xs: Vec<Vec3> = (0..2).flat_map(|t| mesh.corners(t)).collect();
    xs.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    xs.dedup();
    assert_eq!(xs, [Vec3::ZERO, Vec3::Y, Vec3::X, Vec3::new(1.1, 1.3, 0.0)]);
}

/// `mtllib` with a file name containing spaces, a list of two files, and
/// names whose case differs from the files on disk.
#[test]
fn mtllib_names_with_spaces_lists_and_other_case() {
    let dir = Dir::new("mtllib");
    dir.write("My Materials.mtl", "newmtl red\nKd 1 0 0\n");
    dir.write("a.mtl", "newmtl green\nKd 0 1 0\n");
    dir.write("B.MTL", "newmtl blue\nKd 0 0 1\n");
    dir.write(
        "m.obj",
        "mtllib   My Materials.mtl  \nmtllib a.mtl b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
         usemtl red\nf 1 2 3\nusemtl green\nf 1 2 3\nusemtl blue\nf 1 2 3\n",
    );
    let s = dir.load("m.obj").unwrap();
    let mesh = &s.objects[0].mesh;
    let albedo: Vec<Vec3> = (mesh.material_ids.iter())
        .map(|&i| s.materials[i as usize].albedo)
        .collect();
    assert_eq!(albedo, [Vec3::X, Vec3::Y, Vec3::Z]);

    // A missing file among several names: the error names the statement.
    let dir = Dir::new("mtllib-missing");
    dir.write("a.mtl", "newmtl green\nKd 0 1 0\n");
    let obj = dir.write("m.obj", "v 0 0 0\nmtllib a.mtl gone.mtl\n");
    match dir.load("m.obj") {
        Err(Error::File {
            path,
            line,
            message,
        }) => {
            assert_eq!((path, line), (obj, Some(2)), "{message}");
            assert!(message.contains("a.mtl gone.mtl"), "{message}");
        }
        other => panic!("expected an error at m.obj:2, got {other:?}"),
    }
}

/// Texture paths as Windows exporters write them: backslashes, another
/// letter case than the file on disk, an absolute path from the
/// exporter's machine (the bare name is found next to the MTL), and
/// `map_*` options before the name. All resolve to the one texture file.
#[test]
fn texture_paths_and_options_as_exporters_write_them() {
    let dir = Dir::new("tex");
    dir.write("Textures/Red Brick.png", png());
    dir.write("Textures/mask.png", png());
    let statements = [
        "map_Kd textures\\red brick.png",
        "map_Kd -s 1 1 1 -o 0 0 0 -bm 0.5 -clamp on .\\TEXTURES\\Red Brick.PNG",
        "map_Kd -blendu off -blendv off -mm 0 1 -texres 512 -imfchan r -cc on Textures/Red Brick.png",
        "map_Kd C:\\Users\\artist\\Red Brick.png",
        "map_Kd -unknown 1 2 on textures/red brick.png",
        "map_Kd ébauche/../Textures/Red Brick.png",
    ];
    // The bare-name fallback finds this copy next to the MTL.
    dir.write("Red Brick.png", png());
    for statement in statements {
        dir.write(
            "m.mtl",
            format!("newmtl a\nKd 1 1 1\n{statement}\nmap_d -clamp on textures\\MASK.png\n"),
        );
        dir.write("m.obj", quad_obj("m.mtl", "a"));
        let s = dir
            .load("m.obj")
            .unwrap_or_else(|e| panic!("{statement}: {e}"));
        let m = &s.materials[s.objects[0].mesh.material_ids[0] as usize];
        assert_eq!(s.textures.len(), 2, "{statement}");
        let albedo = &s.textures[m.albedo_texture.expect(statement)];
        assert!(
            albedo.path.ends_with("Red Brick.png")
                && matches!(&albedo.data, TextureData::Rgb(t) if t.len() == 4),
            "{statement}: {}",
            albedo.path.display()
        );
        let mask = &s.textures[m.opacity_texture.expect(statement)];
        let TextureData::Scalar(alpha) = &mask.data else {
            panic!("{statement}: the mask is scalar")
        };
        // Three opaque texels and one transparent.
        assert_eq!(
            alpha.iter().filter(|&&a| a == 0.0).count(),
            1,
            "{statement}"
        );
    }

    // Options and no name: an error at the statement.
    let dir = Dir::new("tex-noname");
    dir.write("m.obj", quad_obj("m.mtl", "a"));
    let mtl = dir.write("m.mtl", "newmtl a\nmap_Kd -s 2 2 -clamp on\n");
    match dir.load("m.obj") {
        Err(Error::File {
            path,
            line,
            message,
        }) => {
            assert_eq!((path, line), (mtl, Some(2)), "{message}");
            assert!(message.contains("no file name"), "{message}");
        }
        other => panic!("expected an error at m.mtl:2, got {other:?}"),
    }
}

/// `Tr` (transparency, 1 − d) where an exporter writes no `d`; `d` wins
/// when both are given. `Ka`, `Ke`, `Ni`, `Tf`, `illum`, `map_Ka`, `bump`
/// and unknown statements are ignored, even with junk arguments.
#[test]
fn tr_and_unused_statements() {
    let dir = Dir::new("tr");
    dir.write(
        "m.mtl",
        "newmtl tr\nKd 0.5 0.5 0.5\nTr 0.25\n\
         newmtl both\nd 0.9\nTr 0.9\n\
         newmtl junk\nKa junk\nKe 1 2\nNi\nTf x y z\nillum nine\nmap_Ka\nbump -bm 2\n\
         map_bump x.png\nrefl -type sphere r.png\nvendor_ext 1 2 3\nKd 0.2 0.3 0.4\n",
    );
    dir.write(
        "m.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
         usemtl tr\nf 1 2 3\nusemtl both\nf 1 2 3\nusemtl junk\nf 1 2 3\n",
    );
    let s = dir.load("m.obj").unwrap();
    let m: Vec<_> = (s.objects[0].mesh.material_ids.iter())
        .map(|&i| &s.materials[i as usize])
        .collect();
    assert_eq!(m[0].opacity, 0.75);
    assert_eq!(m[1].opacity, 0.9);
    assert_eq!((m[2].albedo, m[2].opacity), (Vec3::new(0.2, 0.3, 0.4), 1.0));
    assert!(m[2].albedo_texture.is_none() && m[2].opacity_texture.is_none());
}

/// The quirks above print only what they must: a scene whose OBJ uses
/// every ignored statement loads through the CLI with nothing on stderr,
/// and the zero-normal fallback prints exactly one line that counts.
#[test]
fn warnings_are_one_line_or_none() {
    let dir = Dir::new("quiet");
    dir.write(
        "m.mtl",
        "\u{feff}newmtl a\nKa 0 0 0\nKe 0 0 0\nillum 2\nNi 1.5\nTr 0\nd 1\nKd 0.5 0.5 0.5\n",
    );
    dir.write(
        "quiet.obj",
        "mtllib m.mtl\ng a\no b\ns 1\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nusemtl a\nf 1//1 2//1 3//1\n",
    );
    // 5 zero normals, used by 5 corners of 3 triangles.
    dir.write(
        "loud.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\n\
         vn 0 0 0\nvn 0 0 0\nvn 0 0 0\nvn 0 0 0\nvn 0 0 0\n\
         f 1//2 2//3 3//1\nf 2//4 4//5 3//1\nf 1//6 2//1 4//1\n",
    );
    let stderr_of = |obj: &str| {
        let scene = dir.write(
            &format!("{obj}.toml"),
            format!("[camera]\neye = [0.5, 0.5, 3.0]\ntarget = [0.5, 0.5, 0.0]\nfov_y = 45.0\n[[object]]\nobj = \"{obj}\"\n"),
        );
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
            .arg("info")
            .arg(&scene)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{obj}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stderr).unwrap()
    };
    assert_eq!(stderr_of("quiet.obj"), "");
    let loud = stderr_of("loud.obj");
    assert_eq!(loud.lines().count(), 1, "{loud}");
    assert!(
        loud.contains("loud.obj:6:")
            && loud.contains("5 zero or non-finite")
            && loud.contains(" 5 triangle corner"),
        "{loud}"
    );
}

/// The Dabrovic Sponza (one zero `vn` at line 232632, unnormalised
/// normals, 68 `g` and 16k `s` lines) loads whole, with unit normals.
#[test]
fn dabrovic_sponza_loads() {
    let obj =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models/dabrovic-sponza/sponza.obj");
    let dir = Dir::new("dabrovic");
    let s = dir.load(obj.to_str().unwrap()).unwrap();
    let mesh = &s.objects[0].mesh;
    // 66,454 faces, one of them degenerate (dropped by the loader).
    assert_eq!(mesh.triangle_count(), 66_453);
    let normals = mesh.normals.as_ref().unwrap();
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    assert!(mesh.uvs.is_some());
    let (lo, hi) = s.bounds().unwrap();
    assert!(
        lo.abs_diff_eq(Vec3::new(-17.40276, -0.906689, -7.798512), 1e-4),
        "{lo}"
    );
    assert!(
        hi.abs_diff_eq(Vec3::new(17.41724, 15.653312, 7.801489), 1e-4),
        "{hi}"
    );
}

/// A plain file (positions and triangles only) takes the parallel path;
/// the same file with one statement that path does not take (an unused
/// `vt`) takes the scan and tobj. Both give the same scene, bit for bit:
/// positions, triangles, materials, no normals or uvs. Large enough for
/// several of the plain path's 1 MiB chunks, with faces that reuse,
/// skip and reorder vertices, comments, `s` lines and CRLF ends.
#[test]
fn a_plain_obj_loads_as_the_general_path_loads_it() {
    let dir = Dir::new("plain");
    let mut text = String::from("# plain\r\n");
    let n = 60_000u32;
    let mut state = 12345u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as u32
    };
    for i in 0..n {
        let c = |r: u32| (r as f32 / u32::MAX as f32 - 0.5) * 0.01 + (i as f32) * 1e-5;
        text += &format!("v {} {:e} {}\n", c(next()), c(next()), c(next()));
        if i % 1000 == 0 {
            text += "s 1\r\n";
        }
    }
    for _ in 0..90_000 {
        let pick = |r: u32| 1 + r % (n - 7);
        let a = pick(next());
        text += &format!("f {a} {} {}\n", a + 1 + next() % 3, a + 4 + next() % 3);
    }
    assert!(text.len() > 3 << 20);
    dir.write("plain.obj", &text);
    dir.write("general.obj", format!("{text}vt 0 0\n"));
    let plain = dir.load("plain.obj").expect("the plain file loads");
    let general = dir.load("general.obj").expect("the general file loads");
    let (a, b) = (&plain.objects[0].mesh, &general.objects[0].mesh);
    let bits = |m: &penumbra::internal::geom::Mesh| -> Vec<[u32; 3]> {
        m.positions
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(a), bits(b));
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.material_ids, b.material_ids);
    assert_eq!(a.normals, b.normals);
    assert_eq!(a.uvs, b.uvs);
    assert_eq!(a.triangle_count(), 90_000);
}
