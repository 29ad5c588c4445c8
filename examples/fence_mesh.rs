//! The fence of `scenes/fence.toml` as geometry instead of a perforated
//! quad, for the speed comparison of soft textured shadow volumes against
//! depth complexity sampling on a mesh (thesis §5.4, Fig. 5.8; results in
//! docs/algorithms/stsv.md, "Speed: perforated triangles vs mesh").
//!
//! Every opaque texel of `scenes/fence-opacity.png` (alpha ≥ 128: the
//! texture is binary) becomes geometry over exactly the part of the quad
//! the texel covers under the quad's uv mapping, so the mesh casts the
//! shadow the nearest look-up gives the quad:
//!
//! - `sheet` (default): one quad (two triangles) per opaque texel in the
//!   fence's plane, vertices welded on the texel grid, an open surface;
//! - `slab T`: the closed surface of the opaque texels extruded to a
//!   thickness of `T` texels centred on the plane (both faces per texel,
//!   side walls where an opaque texel borders a hole), a closed mesh like
//!   a real wire fence's.
//!
//! Writes `fence-mesh.obj` and `fence-mesh.toml` (the shipped scene with
//! the fence object swapped for the OBJ, same transform and albedo) into
//! the output directory (default `target/fence-mesh`):
//!
//! ```text
//! cargo run --release --example fence_mesh -- [OUT_DIR] [sheet | slab T]
//! ```
//!
//! Not a `penumbra` subcommand: a generator for one measurement.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A side wall: the neighbour's offset, the wall's two grid corners and
/// its outward normal.
type Side = ((i64, i64), [(u32, u32); 2], [f64; 3]);

/// Vertices on the texel grid, welded: `(column, row, layer)` → index.
#[derive(Default)]
struct Mesh {
    index: HashMap<(u32, u32, u8), u32>,
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// The quad's object space: `x = 2 (c / W − 1/2)`, `z = 2 (r / H − 1/2)`
    /// (`scene::shapes::quad` of size 2 × 2: `u = x / 2 + 1/2`,
    /// `v = 1/2 − z / 2`, and the texture's row is `(1 − v) H`), `y` the
    /// layer's offset.
    fn vertex(&mut self, c: u32, r: u32, layer: u8, w: u32, h: u32, half: f64) -> u32 {
        let next = self.positions.len() as u32;
        *self.index.entry((c, r, layer)).or_insert_with(|| {
            let y = match layer {
                0 => -half,
                1 => half,
                _ => 0.0,
            };
            self.positions.push([
                2.0 * (f64::from(c) / f64::from(w) - 0.5),
                y,
                2.0 * (f64::from(r) / f64::from(h) - 0.5),
            ]);
            next
        })
    }

    /// Quad `a b c d` (a loop) as two triangles, wound so that the first
    /// triangle's normal points along `out`.
    fn quad(&mut self, [a, b, c, d]: [u32; 4], out: [f64; 3]) {
        let p = |i: u32| self.positions[i as usize];
        let (pa, pb, pc) = (p(a), p(b), p(c));
        let u = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
        let v = [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]];
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let along = n[0] * out[0] + n[1] * out[1] + n[2] * out[2];
        if along >= 0.0 {
            self.triangles.push([a, b, c]);
            self.triangles.push([a, c, d]);
        } else {
            self.triangles.push([a, c, b]);
            self.triangles.push([a, d, c]);
        }
    }
}

fn main() {
    if let Err(e) = run() {
        eprintln!("fence_mesh: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out_dir = args
        .first()
        .map_or_else(|| root.join("target/fence-mesh"), PathBuf::from);
    let thickness = match args.get(1).map(String::as_str) {
        None | Some("sheet") => None,
        Some("slab") => {
            let t: f64 = args
                .get(2)
                .ok_or("slab needs a thickness in texels")?
                .parse()
                .map_err(|e| format!("slab thickness: {e}"))?;
            if !(t.is_finite() && t > 0.0) {
                return Err(format!("slab thickness {t} must be positive"));
            }
            Some(t)
        }
        Some(other) => return Err(format!("unknown mode `{other}` (sheet | slab T)")),
    };

    let png = root.join("scenes/fence-opacity.png");
    let img = image::open(&png)
        .map_err(|e| format!("{}: {e}", png.display()))?
        .to_rgba8();
    let (w, h) = img.dimensions();
    let opaque = |c: i64, r: i64| {
        c >= 0
            && r >= 0
            && c < i64::from(w)
            && r < i64::from(h)
            && img.get_pixel(c as u32, r as u32)[3] >= 128
    };

    let mut mesh = Mesh::default();
    // Half the thickness in object units (a texel is 2 / W wide).
    let half = thickness.map_or(0.0, |t| 0.5 * t * 2.0 / f64::from(w));
    let mut texels = 0usize;
    for r in 0..h {
        for c in 0..w {
            if !opaque(i64::from(c), i64::from(r)) {
                continue;
            }
            texels += 1;
            let (ci, ri) = (i64::from(c), i64::from(r));
            match thickness {
                None => {
                    let mut v = |dc, dr| mesh.vertex(c + dc, r + dr, 2, w, h, half);
                    let q = [v(0, 1), v(1, 1), v(1, 0), v(0, 0)];
                    mesh.quad(q, [0.0, 1.0, 0.0]);
                }
                Some(_) => {
                    for (layer, up) in [(1u8, 1.0), (0u8, -1.0)] {
                        let mut v = |dc, dr| mesh.vertex(c + dc, r + dr, layer, w, h, half);
                        let q = [v(0, 1), v(1, 1), v(1, 0), v(0, 0)];
                        mesh.quad(q, [0.0, up, 0.0]);
                    }
                    // Side walls towards holes (and the texture's border).
                    let sides: [Side; 4] = [
                        ((1, 0), [(c + 1, r), (c + 1, r + 1)], [1.0, 0.0, 0.0]),
                        ((-1, 0), [(c, r), (c, r + 1)], [-1.0, 0.0, 0.0]),
                        ((0, 1), [(c, r + 1), (c + 1, r + 1)], [0.0, 0.0, 1.0]),
                        ((0, -1), [(c, r), (c + 1, r)], [0.0, 0.0, -1.0]),
                    ];
                    for ((dc, dr), [p, q], out) in sides {
                        if opaque(ci + dc, ri + dr) {
                            continue;
                        }
                        let quad = [
                            mesh.vertex(p.0, p.1, 0, w, h, half),
                            mesh.vertex(q.0, q.1, 0, w, h, half),
                            mesh.vertex(q.0, q.1, 1, w, h, half),
                            mesh.vertex(p.0, p.1, 1, w, h, half),
                        ];
                        mesh.quad(quad, out);
                    }
                }
            }
        }
    }

    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let mut obj = String::new();
    let _ = writeln!(
        obj,
        "# scenes/fence-opacity.png's {texels} opaque texels as {} triangles ({}), \
         written by examples/fence_mesh.rs",
        mesh.triangles.len(),
        thickness.map_or("sheet".to_string(), |t| format!("slab {t} texels thick"))
    );
    for p in &mesh.positions {
        let _ = writeln!(obj, "v {} {} {}", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        let _ = writeln!(obj, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let obj_path = out_dir.join("fence-mesh.obj");
    std::fs::write(&obj_path, obj).map_err(|e| format!("{}: {e}", obj_path.display()))?;

    // The shipped scene with the fence object swapped: same transform,
    // same albedo, no opacity texture.
    let scene_path = root.join("scenes/fence.toml");
    let scene = std::fs::read_to_string(&scene_path)
        .map_err(|e| format!("{}: {e}", scene_path.display()))?;
    let swaps = [
        (
            "name = \"fence\"\nshape = \"quad\"\nsize = [2.0, 2.0]\n",
            "name = \"fence\"\nobj = \"fence-mesh.obj\"\n",
        ),
        (
            "material = { albedo = [0.55, 0.55, 0.6], opacity_texture = \"fence-opacity.png\" }",
            "material = { albedo = [0.55, 0.55, 0.6] }",
        ),
        (
            "name = \"fence\"\nambient",
            // Distinct names: `penumbra compare` puts each scene in a
            // directory named after it.
            if thickness.is_some() {
                "name = \"fence-slab\"\nambient"
            } else {
                "name = \"fence-sheet\"\nambient"
            },
        ),
    ];
    let mut mesh_scene = scene;
    for (from, to) in swaps {
        if !mesh_scene.contains(from) {
            return Err(format!(
                "{} changed: `{from}` not found; update examples/fence_mesh.rs",
                scene_path.display()
            ));
        }
        mesh_scene = mesh_scene.replacen(from, to, 1);
    }
    let mesh_scene = format!(
        "# Generated by examples/fence_mesh.rs from scenes/fence.toml: the fence\n\
         # as {} triangles instead of two S-triangles.\n{mesh_scene}",
        mesh.triangles.len()
    );
    let toml_path = out_dir.join("fence-mesh.toml");
    std::fs::write(&toml_path, mesh_scene).map_err(|e| format!("{}: {e}", toml_path.display()))?;
    println!(
        "{}: {} opaque texels, {} vertices, {} triangles; scene {}",
        obj_path.display(),
        texels,
        mesh.positions.len(),
        mesh.triangles.len(),
        toml_path.display()
    );
    Ok(())
}
