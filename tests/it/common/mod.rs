//! Helpers shared by the integration tests.
#![allow(dead_code)]

/// SplitMix64: a tiny, seeded, reproducible generator for property tests.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform integer in [lo, hi].
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as i64
    }
}

/// A unique scratch directory for one test.
pub fn scratch_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("penumbra-test-{}-{}", name, std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// A scratch directory (see [`scratch_dir`]) removed when dropped.
#[allow(dead_code)]
pub struct ScratchDir(pub std::path::PathBuf);

#[allow(dead_code)]
impl ScratchDir {
    pub fn new(name: &str) -> ScratchDir {
        ScratchDir(scratch_dir(name))
    }

    /// Writes `content` to `name` in the directory; its path.
    pub fn write(&self, name: &str, content: impl AsRef<[u8]>) -> std::path::PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, content).expect("write scratch file");
        path
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Loads a scene file written, with extra files (name, bytes), into a
/// scratch directory.
pub fn scene_in_scratch(
    name: &str,
    toml: &str,
    files: &[(&str, &[u8])],
) -> penumbra::internal::scene::Scene {
    // A directory of its own per call: tests running at once may load the
    // same named scene, and one's clean-up must not remove (or its write
    // truncate) the file another is reading.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = scratch_dir(&format!("{name}-{call}"));
    for (file, bytes) in files {
        std::fs::write(dir.join(file), bytes).expect("write scratch file");
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).expect("write scene");
    let scene = penumbra::internal::scene::load_scene(&path).expect("test scene loads");
    // Everything is in memory now: leave nothing behind in the temp dir.
    let _ = std::fs::remove_dir_all(&dir);
    scene
}

/// Loads a scene shipped in `scenes/`.
pub fn shipped(name: &str) -> penumbra::internal::scene::Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    penumbra::internal::scene::load_scene(&path).expect("shipped scene loads")
}

/// `scene` with its first light (a rect) made a sphere of radius `radius`
/// at the same centre.
#[allow(dead_code)]
pub fn with_sphere_light(
    mut scene: penumbra::internal::scene::Scene,
    radius: f32,
) -> penumbra::internal::scene::Scene {
    use penumbra::internal::scene::LightShape;
    let LightShape::Rect { center, .. } = scene.lights[0].shape else {
        panic!("a rect light");
    };
    scene.lights[0].shape = LightShape::Sphere { center, radius };
    scene
}

/// Everything a technique reads, for `scene` at `w × h`.
pub struct Frame {
    pub geometry: penumbra::internal::geom::SceneGeometry,
    pub view: penumbra::internal::view::View,
    pub gbuffer: penumbra::internal::gbuffer::GBuffer,
    pub depth: penumbra::internal::raster::Framebuffer,
}

impl Frame {
    pub fn new(scene: &penumbra::internal::scene::Scene, w: u32, h: u32) -> Frame {
        let options = penumbra::internal::render::RenderOptions {
            width: Some(w),
            height: Some(h),
            ..penumbra::internal::render::RenderOptions::default()
        };
        let view = penumbra::internal::render::view_for(scene, &options).expect("view");
        let geometry = penumbra::internal::geom::SceneGeometry::new(scene);
        let (gbuffer, depth, _) =
            penumbra::internal::gbuffer::gbuffer_pass(scene, &geometry, &view).expect("g-buffer");
        Frame {
            geometry,
            view,
            gbuffer,
            depth,
        }
    }

    pub fn ctx<'a>(
        &'a self,
        scene: &'a penumbra::internal::scene::Scene,
    ) -> penumbra::internal::shadow::ShadowContext<'a> {
        // A test's few contexts each get their own cache, leaked: the
        // context must borrow it for as long as the frame, and tests are
        // short-lived processes.
        let cache: &'a penumbra::internal::shadow::ShadowCache<'a> = Box::leak(Box::new(
            penumbra::internal::shadow::ShadowCache::new(scene, &self.geometry),
        ));
        penumbra::internal::shadow::ShadowContext {
            scene,
            geometry: &self.geometry,
            view: &self.view,
            gbuffer: &self.gbuffer,
            depth: &self.depth,
            cache,
            observer: &penumbra::internal::observe::Silent,
        }
    }

    /// Index of the surface pixel whose position is closest to `p`.
    pub fn pixel_near(&self, p: glam::Vec3) -> usize {
        let mut best = (f32::INFINITY, usize::MAX);
        for (i, g) in self.gbuffer.samples().enumerate() {
            let d = g.position.distance(p);
            if g.is_surface() && d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }
}

/// Distance between segments `p0 p1` and `q0 q1` (sampled closely
/// enough for a tie measure: exact at the closest-point solution).
pub fn segment_distance(p0: glam::DVec3, p1: glam::DVec3, q0: glam::DVec3, q1: glam::DVec3) -> f64 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    let (c, b) = (d1.dot(r), d1.dot(d2));
    let denom = a * e - b * b;
    let mut s = if denom > 1e-300 {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = if e > 0.0 { (b * s + f) / e } else { 0.0 };
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (p0 + d1 * s).distance(q0 + d2 * t)
}

/// Every bit of a render's radiance and layers (for bit-identity checks).
pub fn render_bits(out: &penumbra::internal::render::Render) -> Vec<u32> {
    let mut v: Vec<u32> = out
        .radiance
        .iter()
        .flat_map(|c| c.to_array().map(f32::to_bits))
        .collect();
    for layer in &out.layers {
        for (_, channel) in &layer.channels {
            v.extend(channel.iter().map(|x| x.to_bits()));
        }
    }
    v
}

/// The sampling under which an exact technique's samples are the
/// reference's own: the defaults, except for penumbra casting, whose K
/// shared sample sets equal the reference's per-pixel samples with
/// `interleaved:2` and four sets (its default, 8 sets of a decorrelated
/// pattern, is exact for samples that are not the reference's). Render the
/// reference with the same pattern.
pub fn matched_sampling(
    technique: penumbra::internal::shadow::Technique,
) -> (
    penumbra::internal::shadow::TechniqueOptions,
    penumbra::internal::sampling::SamplePattern,
) {
    let mut options = penumbra::internal::shadow::TechniqueOptions::default();
    let mut pattern = penumbra::internal::sampling::SamplePattern::default();
    if technique.name() == "penumbra-casting" {
        options.penumbra_casting.pc_sample_sets = 4;
        pattern = penumbra::internal::sampling::SamplePattern::Interleaved { n: 2 };
    }
    (options, pattern)
}

/// Render options for DCS's cost choice tests: `technique` at `side`²,
/// 16 samples, with `--dcs-rays` set to `rays`.
pub fn dcs_rays_options(
    technique: &str,
    side: u32,
    rays: penumbra::internal::shadow::dcs::RayChoice,
) -> penumbra::internal::render::RenderOptions {
    let mut techniques = penumbra::internal::shadow::TechniqueOptions::default();
    techniques.dcs.rays = rays;
    penumbra::internal::render::RenderOptions {
        width: Some(side),
        height: Some(side),
        technique: technique.parse().expect("a technique"),
        samples: 16,
        options: techniques,
        ..Default::default()
    }
}

/// The first light's Vcoef, whichever term the render kept.
pub fn first_light_vcoef(r: &penumbra::internal::render::Render) -> &[f32] {
    use penumbra::internal::shadow::LightTerm;
    match &r.lights[0] {
        LightTerm::Vcoef(v) | LightTerm::Radiance { vcoef: v, .. } => v,
    }
}

/// Whether DCS traced the first light (its cost choice), from the pass
/// it then runs.
pub fn first_light_traced(r: &penumbra::internal::render::Render) -> bool {
    r.passes.iter().any(|p| p.name == "rays light 0")
}
