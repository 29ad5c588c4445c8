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

/// Loads a scene file written, with extra files (name, bytes), into a
/// scratch directory.
pub fn scene_in_scratch(name: &str, toml: &str, files: &[(&str, &[u8])]) -> penumbra::scene::Scene {
    let dir = scratch_dir(name);
    for (file, bytes) in files {
        std::fs::write(dir.join(file), bytes).expect("write scratch file");
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).expect("write scene");
    penumbra::scene::load_scene(&path).expect("test scene loads")
}

/// Loads a scene shipped in `scenes/`.
pub fn shipped(name: &str) -> penumbra::scene::Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    penumbra::scene::load_scene(&path).expect("shipped scene loads")
}
