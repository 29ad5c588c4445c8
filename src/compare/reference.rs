//! The reference every run is measured against: two independent
//! half-sample references, computed once and kept in the disk cache
//! ([`cache`](super::cache)); their mean as the reference images, half
//! their difference as the reference's own error (its noise floor).

use super::cache::{
    self, CachedReference, ReferenceHalf, ReferenceKey, StableHasher, REFERENCE_VERSION,
};
use super::model::{NoiseFloor, RegionMetrics};
use super::settings::CompareOptions;
use crate::error::{Error, Result};
use crate::output::srgb8;
use crate::render::{estimate_render, render, render_with, Aov, Render, RenderOptions, Technique};
use crate::report::{
    error_metrics, flip_rgb8, interior_mask, ErrorAccumulator, FlipRegions, Progress,
};
use crate::scene::Scene;
use glam::Vec3;
use std::time::Instant;

impl NoiseFloor {
    /// Half the error between the two halves (see the module docs).
    fn from_halves(m: RegionMetrics) -> Self {
        NoiseFloor {
            rmse_all: m.all.rmse / 2.0,
            mae_all: m.all.mean_abs / 2.0,
            rmse_penumbra: m.penumbra.rmse / 2.0,
            mae_penumbra: m.penumbra.mean_abs / 2.0,
            rmse_interior: m.interior.rmse / 2.0,
            mae_interior: m.interior.mean_abs / 2.0,
        }
    }
}

/// The reference's noise floors: Vcoef per light and over all lights,
/// and radiance; and FLIP between its halves.
pub(super) struct NoiseFloors {
    /// Vcoef per light.
    pub vcoef: Vec<NoiseFloor>,
    /// Vcoef over all lights.
    pub vcoef_all_lights: NoiseFloor,
    /// Radiance.
    pub radiance: NoiseFloor,
    /// FLIP of the second half against the first.
    pub flip_halves: FlipRegions,
}

impl NoiseFloors {
    /// The floors of `cached`'s two halves (`width × height` images) over
    /// `reference`'s regions.
    pub fn new(
        cached: &CachedReference,
        reference: &ReferenceImages,
        (width, height): (u32, u32),
    ) -> Self {
        let halves = &cached.halves;
        let vcoef: Vec<NoiseFloor> = (0..reference.vcoef.len())
            .map(|k| {
                NoiseFloor::from_halves(reference.vcoef_metrics_of(
                    k,
                    &halves[0].vcoef[k],
                    &halves[1].vcoef[k],
                ))
            })
            .collect();
        let half_a: Vec<Option<&[f32]>> =
            halves[0].vcoef.iter().map(|v| Some(v.as_slice())).collect();
        let vcoef_all_lights = reference
            .vcoef_all_lights(&half_a, &halves[1].vcoef)
            .map(NoiseFloor::from_halves)
            .unwrap_or_default();
        let radiance = NoiseFloor::from_halves(
            reference.radiance_metrics(&halves[0].radiance, &halves[1].radiance),
        );
        let flip_halves = flip_rgb8(
            &srgb8(&halves[0].radiance),
            &srgb8(&halves[1].radiance),
            width,
            height,
        )
        .map(|map| map.regions(&reference.interior))
        .unwrap_or_default();
        NoiseFloors {
            vcoef,
            vcoef_all_lights,
            radiance,
            flip_halves,
        }
    }
}

/// The reference images a comparison measures against.
pub(super) struct ReferenceImages {
    /// Per pixel: it sees a surface.
    pub surface: Vec<bool>,
    /// Per pixel: a surface away from geometric edges
    /// ([`crate::report::interior`]).
    pub interior: Vec<bool>,
    /// The halves' mean radiance.
    pub radiance: Vec<Vec3>,
    /// `radiance` tone-mapped as the PNG output is (FLIP's reference).
    pub rgb8: Vec<u8>,
    /// Per light: the halves' mean Vcoef.
    pub vcoef: Vec<Vec<f32>>,
    /// Per light: reference Vcoef strictly inside (0, 1).
    pub penumbra: Vec<Vec<bool>>,
    /// Some light in penumbra.
    penumbra_any: Vec<bool>,
}

impl ReferenceImages {
    /// The mean of `cached`'s halves and its regions: penumbra, and
    /// `interior` (shading points of the reference only).
    pub fn new(cached: &CachedReference, interior: &[bool]) -> Self {
        let [a, b] = &cached.halves;
        let surface: Vec<bool> = cached.mask.iter().map(|&m| m > 0.5).collect();
        let interior = (0..surface.len())
            .map(|i| surface[i] && interior.get(i).copied().unwrap_or(false))
            .collect();
        let radiance: Vec<Vec3> = a
            .radiance
            .iter()
            .zip(&b.radiance)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect();
        let vcoef: Vec<Vec<f32>> = a
            .vcoef
            .iter()
            .zip(&b.vcoef)
            .map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p + q) * 0.5).collect())
            .collect();
        let penumbra: Vec<Vec<bool>> = vcoef
            .iter()
            .map(|v| {
                v.iter()
                    .zip(&surface)
                    .map(|(&v, &s)| s && v > 0.0 && v < 1.0)
                    .collect()
            })
            .collect();
        let penumbra_any = (0..surface.len())
            .map(|i| penumbra.iter().any(|p| p[i]))
            .collect();
        ReferenceImages {
            surface,
            interior,
            rgb8: srgb8(&radiance),
            radiance,
            vcoef,
            penumbra,
            penumbra_any,
        }
    }

    /// Light `k`'s Vcoef error of `test`.
    pub fn vcoef_metrics(&self, k: usize, test: &[f32]) -> RegionMetrics {
        self.vcoef_metrics_of(k, test, &self.vcoef[k])
    }

    /// Light `k`'s Vcoef error of `test` against `against`, over light
    /// `k`'s regions.
    fn vcoef_metrics_of(&self, k: usize, test: &[f32], against: &[f32]) -> RegionMetrics {
        let (s, p, n) = (&self.surface, &self.penumbra[k], &self.interior);
        RegionMetrics {
            all: error_metrics(test, against, |i| s[i]),
            penumbra: error_metrics(test, against, |i| p[i]),
            interior: error_metrics(test, against, |i| n[i]),
        }
    }

    /// Vcoef error over every light's values together (`None` if some
    /// light has no Vcoef).
    pub fn vcoef_all_lights(
        &self,
        tests: &[Option<&[f32]>],
        against: &[Vec<f32>],
    ) -> Option<RegionMetrics> {
        let mut all = ErrorAccumulator::default();
        let mut pen = ErrorAccumulator::default();
        let mut inner = ErrorAccumulator::default();
        for (k, test) in tests.iter().enumerate() {
            let test = (*test)?;
            for (i, (&t, &r)) in test.iter().zip(&against[k]).enumerate() {
                if self.surface[i] {
                    all.add(t as f64, r as f64);
                }
                if self.penumbra[k][i] {
                    pen.add(t as f64, r as f64);
                }
                if self.interior[i] {
                    inner.add(t as f64, r as f64);
                }
            }
        }
        Some(RegionMetrics {
            all: all.finish(),
            penumbra: pen.finish(),
            interior: inner.finish(),
        })
    }

    /// Radiance error of `test` against `against` over R, G and B.
    pub fn radiance_metrics(&self, test: &[Vec3], against: &[Vec3]) -> RegionMetrics {
        let mut all = ErrorAccumulator::default();
        let mut pen = ErrorAccumulator::default();
        let mut inner = ErrorAccumulator::default();
        for (i, (t, r)) in test.iter().zip(against).enumerate() {
            for c in 0..3 {
                if self.surface[i] {
                    all.add(t[c] as f64, r[c] as f64);
                }
                if self.penumbra_any[i] {
                    pen.add(t[c] as f64, r[c] as f64);
                }
                if self.interior[i] {
                    inner.add(t[c] as f64, r[c] as f64);
                }
            }
        }
        RegionMetrics {
            all: all.finish(),
            penumbra: pen.finish(),
            interior: inner.finish(),
        }
    }
}

/// The Vcoef of light `k` of a render, background pixels 0 (as in the
/// `vcoef` AOV the cached references store).
pub(super) fn vcoef_of(out: &Render, k: usize, surface: &[bool]) -> Option<Vec<f32>> {
    let term = out.lights.get(k)?;
    Some(
        term.vcoef()
            .iter()
            .zip(surface)
            .map(|(&v, &s)| if s { v } else { 0.0 })
            .collect(),
    )
}

/// The interior of `scene`'s frame at the comparison's size
/// ([`crate::report::interior`]), from the G-buffer's depth, normals and
/// mask: a render without shadows (`none`) of the same view, so the same
/// G-buffer as the reference's and every run's. Not cached: it costs a
/// G-buffer pass.
pub(super) fn interior_of(scene: &Scene, options: &CompareOptions) -> Result<Vec<bool>> {
    let out = render(
        scene,
        &RenderOptions {
            width: options.width,
            height: options.height,
            aovs: vec![Aov::Depth, Aov::Normal, Aov::Mask],
            technique: Technique::named("none")?,
            ..RenderOptions::default()
        },
    )?;
    let channel = |layer: &str, c: &str| -> Result<&[f32]> {
        out.layers
            .iter()
            .find(|l| l.name == layer)
            .and_then(|l| l.channels.iter().find(|(n, _)| n == c))
            .map(|(_, v)| v.as_slice())
            .ok_or_else(|| Error::param("compare", format!("the G-buffer has no {layer}.{c}")))
    };
    let depth = channel("depth", "Z")?;
    let (x, y, z) = (
        channel("normal", "X")?,
        channel("normal", "Y")?,
        channel("normal", "Z")?,
    );
    let normal: Vec<[f32; 3]> = (0..depth.len()).map(|i| [x[i], y[i], z[i]]).collect();
    let foreground: Vec<bool> = channel("mask", "Y")?.iter().map(|&m| m > 0.5).collect();
    interior_mask(
        out.width as usize,
        out.height as usize,
        depth,
        &normal,
        &foreground,
    )
    .ok_or_else(|| {
        Error::param(
            "compare",
            "the G-buffer's layers are not of the image's size",
        )
    })
}

/// The cache key of `scene`'s reference under `options`.
pub(super) fn reference_key(scene: &Scene, options: &CompareOptions) -> Result<ReferenceKey> {
    let view = options.view(scene)?;
    let mut h = StableHasher::default();
    cache::hash_scene(&mut h, scene);
    Ok(ReferenceKey {
        scene_hash: h.finish(),
        width: view.width,
        height: view.height,
        samples: options.reference_samples,
        seeds: options.reference_seeds(),
        version: REFERENCE_VERSION,
    })
}

/// How long `scene`'s cached reference took when computed, if the cache
/// holds it ([`cache::peek`]: its sidecar only).
pub(super) fn cached_reference_seconds(
    scene: &Scene,
    options: &CompareOptions,
) -> Result<Option<f64>> {
    let key = reference_key(scene, options)?;
    Ok(cache::peek(&options.cache_dir, &key, scene.lights.len()))
}

/// Computes (or reads from the cache) the reference for `scene`.
pub(super) fn reference(
    scene: &Scene,
    options: &CompareOptions,
    progress: &Progress,
) -> Result<(CachedReference, ReferenceKey, bool)> {
    let view_options = RenderOptions {
        width: options.width,
        height: options.height,
        ..RenderOptions::default()
    };
    let key = reference_key(scene, options)?;
    // Shards of a sweep on a shared filesystem compute each reference
    // once: the first to need it holds the cache's lock while the others
    // wait and then read the cache (cache.rs explains the lock).
    let _lock = loop {
        if let Some(hit) = cache::load(&options.cache_dir, &key, scene.lights.len()) {
            progress.step();
            progress.step();
            return Ok((hit, key, true));
        }
        match cache::lock_reference(&options.cache_dir, &key, progress)? {
            cache::Locked::Held(lock) => break Some(lock),
            cache::Locked::Released => continue,
            cache::Locked::Unavailable(why) => {
                eprintln!("penumbra: warning: reference computed without the cache's lock: {why}");
                break None;
            }
        }
    };
    if progress.estimate_shown() {
        // The reference is a sweep's dearest piece: a time estimate that
        // waited for its first half would be blind for a long while.
        // Render's probes (about a sixteenth of one half) time it first.
        let half = RenderOptions {
            technique: Technique::named("reference")?,
            samples: options.reference_samples / 2,
            ..view_options.clone()
        };
        let probes = Instant::now();
        if let Ok(one) = estimate_render(scene, &half) {
            progress.work_expected(2.0 * one.as_secs_f64() + probes.elapsed().as_secs_f64());
        }
    }
    let start = Instant::now();
    let mut halves = Vec::new();
    let mut mask = Vec::new();
    for (i, &seed) in key.seeds.iter().enumerate() {
        progress.stage(&format!("reference half {}/2", i + 1));
        let out = render_with(
            scene,
            &RenderOptions {
                aovs: vec![Aov::Mask],
                technique: Technique::named("reference")?,
                samples: options.reference_samples / 2,
                seed,
                ..view_options.clone()
            },
            progress.cancel(),
        )?;
        mask = out
            .layers
            .iter()
            .find(|l| l.name == "mask")
            .map(|l| l.channels[0].1.clone())
            .unwrap_or_default();
        let surface: Vec<bool> = mask.iter().map(|&m| m > 0.5).collect();
        let vcoef = (0..scene.lights.len())
            .map(|k| vcoef_of(&out, k, &surface).unwrap_or_default())
            .collect();
        halves.push(ReferenceHalf {
            radiance: out.radiance,
            vcoef,
        });
        if i == 0 {
            // Half the reference: the time estimate's first measure.
            progress.work_part(0.5);
        }
        progress.step();
    }
    let [a, b]: [ReferenceHalf; 2] = halves
        .try_into()
        .map_err(|_| Error::param("--reference-samples", "reference halves missing"))?;
    let cached = CachedReference {
        mask,
        halves: [a, b],
        seconds: start.elapsed().as_secs_f64(),
    };
    if let Err(e) = cache::store(&options.cache_dir, &key, &cached) {
        // A read-only cache costs time, not correctness.
        eprintln!("penumbra: warning: reference not cached: {e}");
    }
    Ok((cached, key, false))
}

/// `compare --references-only`: computes (or finds in the cache) the
/// reference of `scene` under `options` and returns its cache file and
/// whether it was already there.
pub fn reference_only(
    scene: &Scene,
    options: &CompareOptions,
    progress: &Progress,
) -> Result<(std::path::PathBuf, bool)> {
    options.validate()?;
    let (_, key, from_cache) = reference(scene, options, progress)?;
    Ok((
        options.cache_dir.join(format!("{}.exr", key.stem())),
        from_cache,
    ))
}
