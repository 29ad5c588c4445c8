//! The on-disk cache of reference images.
//!
//! A reference with thousands of samples per light takes minutes; `compare`
//! computes it once per scene and options and keeps it on disk. The key is
//! a stable hash of everything the reference depends on: the loaded scene's
//! contents (geometry, materials, texels, lights, camera — so a change to
//! any file the scene references invalidates it, not only the TOML), the
//! image size, the sample count, the seeds and a format version bumped
//! whenever the reference's algorithm changes.

use super::host::host_name;
use crate::error::{Error, Result};
use crate::output::{read_image, write_atomically, write_exr, Layer};
use crate::scene::{LightShape, Scene, TextureData};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Bumped whenever the reference's output changes for the same inputs
/// (sampling, epsilons, shading), so that old cache entries are not reused.
pub const REFERENCE_VERSION: u32 = 1;

/// FNV-1a, 64-bit: stable across Rust versions and platforms (the standard
/// library's hashers are not promised to be), fast enough for the megabytes
/// a scene holds, and collisions only cost a wrong cache hit with odds of
/// about 2⁻⁶⁴ per pair of keys.
#[derive(Debug, Clone, Copy)]
pub struct StableHasher(u64);

impl Default for StableHasher {
    fn default() -> Self {
        StableHasher(0xcbf2_9ce4_8422_2325)
    }
}

impl StableHasher {
    /// Feeds bytes.
    pub fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// Feeds a u64 (little-endian).
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }

    /// Feeds an f32 by its bits (so -0.0 and 0.0 differ, as they may in
    /// results).
    pub fn f32(&mut self, v: f32) {
        self.bytes(&v.to_bits().to_le_bytes());
    }

    /// Feeds a vector.
    pub fn vec3(&mut self, v: Vec3) {
        self.f32(v.x);
        self.f32(v.y);
        self.f32(v.z);
    }

    /// Feeds a string with its length (so concatenations cannot collide).
    pub fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.bytes(s.as_bytes());
    }

    /// The hash.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Hashes the loaded scene's contents: everything that can change a
/// rendered pixel. The file path and names are left out, so a copied or
/// renamed scene still hits the cache.
pub fn hash_scene(h: &mut StableHasher, scene: &Scene) {
    h.vec3(scene.ambient);
    h.vec3(scene.background);
    let c = &scene.camera;
    h.vec3(c.eye);
    h.vec3(c.target);
    h.vec3(c.up);
    h.f32(c.fov_y_degrees);
    h.u64(c.width as u64);
    h.u64(c.height as u64);
    h.u64(scene.lights.len() as u64);
    for l in &scene.lights {
        match l.shape {
            LightShape::Rect {
                center,
                u,
                v,
                two_sided,
            } => {
                h.u64(0);
                h.vec3(center);
                h.vec3(u);
                h.vec3(v);
                h.u64(two_sided as u64);
            }
            LightShape::Sphere { center, radius } => {
                h.u64(1);
                h.vec3(center);
                h.f32(radius);
            }
        }
        h.vec3(l.radiance);
        h.u64(l.texture.map_or(u64::MAX, |t| t as u64));
    }
    h.u64(scene.objects.len() as u64);
    for o in &scene.objects {
        let m = &o.mesh;
        h.u64(o.cast_shadows as u64 | (o.receive_shadows as u64) << 1);
        h.u64(m.positions.len() as u64);
        m.positions.iter().for_each(|p| h.vec3(*p));
        match &m.normals {
            Some(n) => {
                h.u64(n.len() as u64);
                n.iter().for_each(|p| h.vec3(*p));
            }
            None => h.u64(u64::MAX),
        }
        match &m.uvs {
            Some(uv) => {
                h.u64(uv.len() as u64);
                uv.iter().for_each(|p| {
                    h.f32(p.x);
                    h.f32(p.y)
                });
            }
            None => h.u64(u64::MAX),
        }
        h.u64(m.triangles.len() as u64);
        for (t, mat) in m.triangles.iter().zip(&m.material_ids) {
            h.bytes(&t[0].to_le_bytes());
            h.bytes(&t[1].to_le_bytes());
            h.bytes(&t[2].to_le_bytes());
            h.bytes(&mat.to_le_bytes());
        }
    }
    h.u64(scene.materials.len() as u64);
    for m in &scene.materials {
        h.vec3(m.albedo);
        h.u64(m.albedo_texture.map_or(u64::MAX, |t| t as u64));
        h.vec3(m.specular);
        h.f32(m.shininess);
        h.f32(m.opacity);
        h.u64(m.opacity_texture.map_or(u64::MAX, |t| t as u64));
    }
    h.u64(scene.textures.len() as u64);
    for t in &scene.textures {
        h.u64(t.width as u64);
        h.u64(t.height as u64);
        match &t.data {
            TextureData::Rgb(px) => {
                h.u64(0);
                px.iter().for_each(|p| h.vec3(*p));
            }
            TextureData::Scalar(px) => {
                h.u64(1);
                px.iter().for_each(|p| h.f32(*p));
            }
        }
    }
}

/// What a cached reference was computed from.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ReferenceKey {
    /// Hash of the scene's contents ([`hash_scene`]).
    pub scene_hash: u64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per light of the whole reference (two halves of half as
    /// many each).
    pub samples: u32,
    /// Seeds of the two halves.
    pub seeds: [u64; 2],
    /// [`REFERENCE_VERSION`].
    pub version: u32,
}

impl ReferenceKey {
    /// The key's file stem: a hash of every field.
    pub fn stem(&self) -> String {
        let mut h = StableHasher::default();
        h.u64(self.scene_hash);
        h.u64(self.width as u64);
        h.u64(self.height as u64);
        h.u64(self.samples as u64);
        h.u64(self.seeds[0]);
        h.u64(self.seeds[1]);
        h.u64(self.version as u64);
        format!("reference-{:016x}", h.finish())
    }
}

/// One half of a reference: radiance and Vcoef per light.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceHalf {
    /// Linear radiance per pixel.
    pub radiance: Vec<Vec3>,
    /// Vcoef per light, per pixel.
    pub vcoef: Vec<Vec<f32>>,
}

/// A reference as two independent halves plus the shading-point mask.
#[derive(Debug, Clone, PartialEq)]
pub struct CachedReference {
    /// 1 where a surface is seen.
    pub mask: Vec<f32>,
    /// The two independent halves.
    pub halves: [ReferenceHalf; 2],
    /// Wall-clock seconds both halves took when computed.
    pub seconds: f64,
}

/// The sidecar written next to a cached reference.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Sidecar {
    key: ReferenceKey,
    seconds: f64,
    lights: usize,
}

/// The cache directory to use when none is given: `$PENUMBRA_CACHE`, else
/// `$XDG_CACHE_HOME/penumbra`, else `$HOME/.cache/penumbra`, else
/// `fallback`.
pub fn default_cache_dir(fallback: &Path) -> PathBuf {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(dir) = var("PENUMBRA_CACHE") {
        return PathBuf::from(dir);
    }
    if let Some(dir) = var("XDG_CACHE_HOME") {
        return PathBuf::from(dir).join("penumbra");
    }
    if let Some(home) = var("HOME") {
        return PathBuf::from(home).join(".cache").join("penumbra");
    }
    fallback.to_path_buf()
}

fn paths(dir: &Path, key: &ReferenceKey) -> (PathBuf, PathBuf) {
    let stem = key.stem();
    (
        dir.join(format!("{stem}.exr")),
        dir.join(format!("{stem}.json")),
    )
}

/// How long the cached reference for `key` took when it was computed,
/// from its sidecar alone (the image is not read): `None` when the cache
/// has no entry for `key` with `lights` lights. A look before the work,
/// for the listing and the time estimate; [`load`] still decides.
pub fn peek(dir: &Path, key: &ReferenceKey, lights: usize) -> Option<f64> {
    let (exr, json) = paths(dir, key);
    let sidecar: Sidecar = serde_json::from_str(&std::fs::read_to_string(json).ok()?).ok()?;
    (sidecar.key == *key && sidecar.lights == lights && exr.is_file()).then_some(sidecar.seconds)
}

/// Reads the cached reference for `key`, if there is a complete and
/// matching one. A missing, stale or corrupt entry is a miss, never an
/// error: the caller recomputes it.
pub fn load(dir: &Path, key: &ReferenceKey, lights: usize) -> Option<CachedReference> {
    let (exr, json) = paths(dir, key);
    let sidecar: Sidecar = serde_json::from_str(&std::fs::read_to_string(json).ok()?).ok()?;
    if sidecar.key != *key || sidecar.lights != lights {
        return None;
    }
    let img = read_image(&exr).ok()?;
    if (img.width, img.height) != (key.width, key.height) {
        return None;
    }
    let half = |prefix: &str| -> Option<ReferenceHalf> {
        let ch = |c: &str| img.channel(&format!("{prefix}{c}"));
        let (r, g, b) = (ch("R")?, ch("G")?, ch("B")?);
        let radiance = r
            .iter()
            .zip(g)
            .zip(b)
            .map(|((r, g), b)| Vec3::new(*r, *g, *b))
            .collect();
        let vcoef = (0..lights)
            .map(|k| ch(&format!("vcoef{k}")).map(<[f32]>::to_vec))
            .collect::<Option<Vec<_>>>()?;
        Some(ReferenceHalf { radiance, vcoef })
    };
    Some(CachedReference {
        mask: img.channel("mask.Y")?.to_vec(),
        halves: [half("half0.")?, half("half1.")?],
        seconds: sidecar.seconds,
    })
}

/// Stores a reference under `key` (atomically: a reader never sees half a
/// file). The EXR is also readable by outside tools: layers `half0` and
/// `half1` hold `R, G, B, vcoef<k>`, `mask.Y` the shading points.
pub fn store(dir: &Path, key: &ReferenceKey, reference: &CachedReference) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (exr, json) = paths(dir, key);
    let mut layers = Vec::new();
    for (i, half) in reference.halves.iter().enumerate() {
        let mut channels = vec![
            ("R".into(), half.radiance.iter().map(|c| c.x).collect()),
            ("G".into(), half.radiance.iter().map(|c| c.y).collect()),
            ("B".into(), half.radiance.iter().map(|c| c.z).collect()),
        ];
        for (k, v) in half.vcoef.iter().enumerate() {
            channels.push((format!("vcoef{k}"), v.clone()));
        }
        layers.push(Layer {
            name: format!("half{i}"),
            channels,
        });
    }
    layers.push(Layer {
        name: "mask".into(),
        channels: vec![("Y".into(), reference.mask.clone())],
    });
    // The top-level radiance is the whole reference, for a quick look.
    let mean: Vec<Vec3> = reference.halves[0]
        .radiance
        .iter()
        .zip(&reference.halves[1].radiance)
        .map(|(a, b)| (*a + *b) * 0.5)
        .collect();
    write_exr(&exr, key.width, key.height, &mean, &layers)?;
    let sidecar = Sidecar {
        key: key.clone(),
        seconds: reference.seconds,
        lights: reference.halves[0].vcoef.len(),
    };
    let text =
        serde_json::to_string_pretty(&sidecar).map_err(|e| Error::param("cache", e.to_string()))?;
    write_atomically(&json, |tmp| {
        std::fs::write(tmp, text.as_bytes()).map_err(|e| Error::io(tmp, e))
    })
}

/// How long a waiter lets a reference lock go unchanged (no heartbeat)
/// before it takes the lock for stale: far above `HEARTBEAT`, so a
/// busy or briefly stalled holder is never robbed.
pub const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(60);

/// How often the holder of a reference lock rewrites it.
const HEARTBEAT: std::time::Duration = std::time::Duration::from_secs(5);

/// How often a waiter looks at the lock and the cache.
const POLL: std::time::Duration = std::time::Duration::from_millis(250);

/// The outcome of [`lock_reference`].
pub enum Locked {
    /// This process holds the lock: compute, store, then drop it.
    Held(ReferenceLock),
    /// Another process held it and let go (or its lock was stale and was
    /// removed): look in the cache again.
    Released,
    /// No lock can be taken (e.g. a read-only cache): compute without one.
    Unavailable(String),
}

/// A held reference lock: `<stem>.lock` in the cache directory, naming its
/// host and pid, rewritten every `HEARTBEAT` by a thread; removed on
/// drop.
pub struct ReferenceLock {
    path: PathBuf,
    token: String,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for ReferenceLock {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
        // Only our own lock: a waiter may have judged us stale and
        // another process may hold the lock now.
        if lock_owner(&self.path).is_some_and(|o| o.token == self.token) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// What a lock file says about its holder.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct LockOwner {
    host: String,
    pid: u32,
    /// Tells this holder from a later one on the same host and pid.
    token: String,
    /// Counts heartbeats: its change is what tells a waiter the holder
    /// lives (clocks of different hosts need not agree, so the waiter
    /// measures the silence on its own clock).
    beat: u64,
}

fn lock_owner(path: &Path) -> Option<LockOwner> {
    serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()
}

/// Whether `owner` is certainly dead: a process of this host that no
/// longer exists (`/proc` tells). Other hosts' holders are judged by
/// their heartbeat only.
fn owner_dead(owner: &LockOwner) -> bool {
    owner.host == host_name()
        && Path::new("/proc/self").exists()
        && !Path::new(&format!("/proc/{}", owner.pid)).exists()
}

/// Takes the lock on computing `key`'s reference in `dir`, or waits while
/// another process holds it.
///
/// The lock is a file created with `create_new` (atomic on local
/// filesystems and on NFSv3+), so of several shards only one computes a
/// reference; the others wait and read the cache. A holder that died is
/// noticed by its pid when on this host, otherwise by a heartbeat that
/// stopped for [`STALE_AFTER`]; its lock is then removed and the waiter
/// tries again. The lock saves work but is not what makes results right:
/// a reference is the same bits whoever computes it and is stored
/// atomically, so the rare race of two computations (a stale-lock
/// judgement crossing a new holder) costs time, never correctness.
pub fn lock_reference(
    dir: &Path,
    key: &ReferenceKey,
    progress: &crate::report::Progress,
) -> Result<Locked> {
    if let Err(e) = std::fs::create_dir_all(dir) {
        return Ok(Locked::Unavailable(format!("{}: {e}", dir.display())));
    }
    let path = dir.join(format!("{}.lock", key.stem()));
    let host = host_name();
    let pid = std::process::id();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let token = format!("{:016x}", {
        let mut h = StableHasher::default();
        h.str(&host);
        h.u64(pid as u64);
        h.u64(nanos);
        h.finish()
    });
    let owner = LockOwner {
        host,
        pid,
        token: token.clone(),
        beat: 0,
    };
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&path)
    {
        Ok(mut file) => {
            use std::io::Write as _;
            let text = serde_json::to_string(&owner).unwrap_or_default();
            if let Err(e) = file
                .write_all(text.as_bytes())
                .and_then(|_| file.sync_all())
            {
                let _ = std::fs::remove_file(&path);
                return Ok(Locked::Unavailable(format!("{}: {e}", path.display())));
            }
            let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let thread = {
                let (stop, path, mut owner) = (stop.clone(), path.clone(), owner);
                std::thread::spawn(move || loop {
                    std::thread::park_timeout(HEARTBEAT);
                    if stop.load(std::sync::atomic::Ordering::Relaxed) {
                        return;
                    }
                    // Someone took the lock for stale: it is theirs now.
                    if lock_owner(&path).is_none_or(|o| o.token != owner.token) {
                        return;
                    }
                    owner.beat += 1;
                    let text = serde_json::to_string(&owner).unwrap_or_default();
                    let _ = std::fs::write(&path, text);
                })
            };
            Ok(Locked::Held(ReferenceLock {
                path,
                token,
                stop,
                thread: Some(thread),
            }))
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            wait_for_lock(&path, dir, key, progress);
            Ok(Locked::Released)
        }
        Err(e) => Ok(Locked::Unavailable(format!("{}: {e}", path.display()))),
    }
}

/// Waits until the lock at `path` is gone, the reference is in the cache,
/// or the lock is stale (then removes it).
fn wait_for_lock(path: &Path, dir: &Path, key: &ReferenceKey, progress: &crate::report::Progress) {
    let (exr, json) = paths(dir, key);
    let mut seen = std::fs::read(path).ok();
    let mut since = std::time::Instant::now();
    if let Some(o) = lock_owner(path) {
        let what = format!(
            "waiting for the reference ({} pid {} computes it)",
            o.host, o.pid
        );
        progress.stage(&what);
        eprintln!("penumbra: {what}: {}", path.display());
    }
    loop {
        let now = std::fs::read(path).ok();
        if now.is_none() || (exr.exists() && json.exists()) {
            return;
        }
        if now != seen {
            seen = now;
            since = std::time::Instant::now();
        }
        let dead = lock_owner(path).is_some_and(|o| owner_dead(&o));
        if dead || since.elapsed() >= STALE_AFTER {
            // Removed only if it is still the lock judged stale.
            if std::fs::read(path).ok() == seen {
                eprintln!(
                    "penumbra: warning: removing stale reference lock {} ({})",
                    path.display(),
                    if dead {
                        "its process is gone"
                    } else {
                        "no heartbeat"
                    }
                );
                let _ = std::fs::remove_file(path);
            }
            return;
        }
        std::thread::sleep(POLL);
    }
}
