//! The S-triangles' share of a light's occlusion, per pixel, for the
//! techniques that keep a visibility coefficient instead of per-sample
//! counters (penumbra wedges and wedge blending, thesis §5.2.1).
//!
//! The thesis ORs, per receiver in an STSV, a bit mask of the light
//! samples its perforated triangles block into a light-sample buffer, then
//! turns the mask into a Vcoef and adds it to the wedges' one. With
//! partial opacities a bit is not enough: per sample we keep the
//! transmittance `Π (1 − α)` over the receiver's S-triangles (for binary
//! opacity exactly the complement of the ORed bit), and the occluded
//! fraction is `f = 1 − mean_k Π (1 − α)`. The samples are the reference's
//! own (same pattern, seed and light), looked up from the reference's
//! shadow-ray origin, so where only S-triangles shadow a receiver `1 − f`
//! is the reference's Vcoef.

use super::{membership, Filter, STriangles, SamplePositions, ShadowOrigin};
use crate::error::{Error, Result};
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::shade::gather::{gather_filter, GatherParams};
use crate::shade::LightSample;
use crate::shadow::kit::tiles::TilePixels;
use crate::shadow::kit::timing::{timed, PassTimer};
use crate::shadow::{BufferNote, PassTiming, ShadowContext};
use rayon::prelude::*;

/// How the S-triangles' occlusion samples a light: the render's sample
/// count, seed and pattern (the reference's, so the two agree sample by
/// sample) and the opacity look-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StsvSampling {
    /// Light samples per receiver in an STSV (`N ≥ 1`).
    pub samples: u32,
    /// Seed of the light samples.
    pub seed: u64,
    /// Layout of the light samples.
    pub pattern: SamplePattern,
    /// Look-up of the opacity textures.
    pub filter: Filter,
}

impl Default for StsvSampling {
    /// The render options' defaults: 64 stratified samples, seed 0,
    /// nearest texel.
    fn default() -> Self {
        StsvSampling {
            samples: 64,
            seed: 0,
            pattern: SamplePattern::Stratified,
            filter: Filter::Nearest,
        }
    }
}

/// One light's S-triangle occlusion.
#[derive(Debug, Clone)]
pub struct StsvOcclusion {
    /// Per pixel (row-major), the fraction of the light the S-triangles
    /// block, in `[0, 1]`; 0 outside every STSV, for background pixels
    /// and for receivers inside a sphere light (no samples).
    pub occluded: Vec<f32>,
    /// `(pixel, S-triangle)` pairs of the membership pass.
    pub pairs: usize,
    /// Receivers whose samples were looked up.
    pub receivers: usize,
}

/// The occluded fraction `1 − mean_k Π (1 − α)` that the S-triangles of
/// `s_triangles` give every receiver of light `light` (soft textured
/// shadow volumes: membership, then per-sample look-ups), timing its
/// passes into `passes`. `None` when there is no S-triangle: the caller
/// then does nothing at all, so scenes without any render exactly as
/// before.
pub fn stsv_occlusion(
    ctx: &ShadowContext,
    s_triangles: &STriangles,
    light: usize,
    sampling: StsvSampling,
    passes: &mut Vec<PassTiming>,
) -> Result<Option<StsvOcclusion>> {
    if s_triangles.is_empty() {
        return Ok(None);
    }
    if sampling.samples == 0 {
        return Err(Error::param(
            "--samples",
            "soft textured shadow volumes need at least 1 light sample",
        ));
    }
    let member = timed(
        passes,
        format!("soft textured shadow volumes light {light}"),
        || membership(ctx, light, s_triangles),
    )?;
    // `membership` has checked that the light exists.
    let Some(l) = ctx.scene.lights.get(light) else {
        return Ok(None);
    };

    let t = PassTimer::start(format!(
        "soft textured shadow volume look-ups light {light}"
    ));
    let sampler = LightSampler::new(l);
    let pattern = PatternSampler::new(sampling.pattern, sampling.samples, sampling.seed, light);
    let origin = ShadowOrigin::new(ctx.scene, ctx.geometry);
    let grid = member.grid;
    let (width, height) = (grid.width as usize, grid.height as usize);

    /// Per-worker buffers.
    #[derive(Default)]
    struct Scratch {
        samples: Vec<LightSample>,
        positions: SamplePositions,
        opacities: Vec<f32>,
        transmittance: Vec<f64>,
    }

    // Tile by tile: each tile's pairs are sorted by local pixel, so a
    // receiver's S-triangles are contiguous.
    let per_tile: Vec<Vec<(usize, f32)>> = member
        .tiles
        .par_iter()
        .enumerate()
        .map_init(Scratch::default, |scratch, (tile, entries)| {
            let mut out = Vec::new();
            let mut e = 0;
            while e < entries.len() {
                let local = (entries[e] >> 32) as usize;
                let first = e;
                while e < entries.len() && (entries[e] >> 32) as usize == local {
                    e += 1;
                }
                let (x, y) = grid.tile_pixel_xy(tile, local);
                if x >= width || y >= height {
                    continue;
                }
                let i = y * width + x;
                if !ctx.gbuffer.is_surface(i) {
                    continue;
                }
                let g = ctx.gbuffer.sample(i);
                sampler.samples_with(
                    &pattern,
                    g.position,
                    (x as u32, y as u32),
                    &mut scratch.samples,
                );
                let n = scratch.samples.len();
                if n == 0 {
                    // Inside a sphere light: no samples, no defined
                    // occlusion (the reference says Vcoef 1 there).
                    continue;
                }
                let Scratch {
                    samples,
                    positions,
                    opacities,
                    transmittance,
                } = scratch;
                positions.set(samples);
                opacities.resize(n, 0.0);
                transmittance.clear();
                transmittance.resize(n, 1.0);
                let o = origin.of(g.position, g.geo_normal);
                for &entry in &entries[first..e] {
                    let s = entry as u32 as usize;
                    s_triangles.sample_opacities_in(
                        ctx.scene,
                        s,
                        o,
                        positions,
                        sampling.filter,
                        opacities,
                    );
                    // f64 like the reference's product along a ray.
                    for (t, &a) in transmittance.iter_mut().zip(opacities.iter()) {
                        *t *= 1.0 - f64::from(a);
                    }
                }
                let mean = transmittance.iter().sum::<f64>() / n as f64;
                out.push((i, (1.0 - mean).clamp(0.0, 1.0) as f32));
            }
            out
        })
        .collect();
    let mut occluded = vec![0.0f32; width * height];
    let mut receivers = 0;
    for (i, f) in per_tile.into_iter().flatten() {
        occluded[i] = f;
        receivers += 1;
    }
    t.finish(passes);
    if let SamplePattern::Interleaved { n } = sampling.pattern {
        // Neighbours used different sample sets: gather them back, as
        // depth complexity sampling does, not across depth or normal
        // discontinuities.
        let t = PassTimer::start(format!("soft textured shadow volume gather light {light}"));
        let guide = |i: usize| {
            let g = ctx.gbuffer.sample(i);
            g.is_surface().then_some((g.depth, g.normal))
        };
        occluded = gather_filter(
            &occluded,
            grid.width,
            grid.height,
            n,
            &guide,
            GatherParams::default(),
        );
        t.finish(passes);
    }
    Ok(Some(StsvOcclusion {
        occluded,
        pairs: member.len(),
        receivers,
    }))
}

/// What `--explain` says about the S-triangles of a Vcoef technique
/// (`technique`: its name), given each light's `(pairs, receivers)`
/// (`None` when there was nothing to do), the image's pixel count and the
/// worker count.
pub fn occlusion_note(
    technique: &str,
    s_triangles: &STriangles,
    sampling: StsvSampling,
    lights: &[Option<(usize, usize)>],
    pixels: u64,
    workers: u64,
) -> BufferNote {
    if s_triangles.is_empty() {
        return BufferNote {
            name: "soft textured shadow volumes".into(),
            detail: "not used: no opacity-textured caster (S-triangle)".into(),
            bytes: 0,
        };
    }
    let n = u64::from(sampling.samples);
    let per_light: Vec<String> = lights
        .iter()
        .enumerate()
        .map(|(k, l)| match l {
            Some((pairs, receivers)) => {
                format!("light {k}: {pairs} (pixel, S-triangle) pairs, {receivers} receivers")
            }
            None => format!("light {k}: none"),
        })
        .collect();
    let pairs: usize = lights.iter().flatten().map(|l| l.0).max().unwrap_or(0);
    BufferNote {
        name: "soft textured shadow volumes".into(),
        detail: format!(
            "{} S-triangles (not wedge casters) shadowed by soft textured shadow volumes \
             (§5.2.1): one volume each per light, (pixel, S-triangle) pairs as u64 per tile; \
             per receiver {n} light samples (the reference's), {} texel look-ups, f64 \
             transmittance Π (1 − α) per sample per worker; the occluded fraction \
             1 − mean Π (1 − α) is added to the {technique} V-buffer (Vcoef −= it, clamped); {}",
            s_triangles.len(),
            match sampling.filter {
                Filter::Nearest => "nearest",
                Filter::Bilinear => "bilinear",
            },
            per_light.join("; ")
        ),
        // Largest light's pairs, the per-pixel f32 result, and per worker
        // the samples, their SoA positions (padded), opacities and
        // transmittances.
        bytes: pairs as u64 * 8
            + pixels * 4
            + workers * n * (std::mem::size_of::<LightSample>() as u64 + 16 + 4 + 8),
    }
}
