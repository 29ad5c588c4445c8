//! Every receiver of a light by its samples' shadow rays, resolved as
//! the counting path resolves opaque counts: the traced side of DCS's
//! cost choice ([`super::plan`]).

use super::receiver::PixelResult;
use super::sample_lanes;
use crate::gbuffer::GSample;
use crate::sampling::{LightSampler, PatternSampler};
use crate::scene::LightShape;
use crate::shade::{surface_point, LightSample, PreparedLight};
use crate::shadow::kit::rays::{LightHull, Scratch as TracerScratch, ShadowTracer};
use crate::shadow::ShadowContext;
use glam::Vec3;

/// One light's receivers by shadow rays: the tracer and what the shading
/// reads, shared by the workers.
pub(super) struct RayPixels<'a, 'c> {
    ctx: &'a ShadowContext<'c>,
    tracer: &'a ShadowTracer<'c>,
    sampler: LightSampler,
    pattern: PatternSampler,
    prepared: &'a PreparedLight<'a>,
    rect: Option<(Vec3, Vec3, Vec3)>,
}

/// One worker's buffers for [`RayPixels::pixel`].
#[derive(Debug, Default)]
pub(super) struct RayScratch {
    samples: Vec<LightSample>,
    vt: Vec<f64>,
    visibility: Vec<f32>,
    tracer: TracerScratch,
}

impl<'a, 'c> RayPixels<'a, 'c> {
    /// Light `light`'s receivers under `pattern`, shaded by `prepared`.
    pub(super) fn new(
        ctx: &'a ShadowContext<'c>,
        tracer: &'a ShadowTracer<'c>,
        light: usize,
        pattern: PatternSampler,
        prepared: &'a PreparedLight<'a>,
    ) -> Self {
        let l = &ctx.scene.lights[light];
        let rect = match l.shape {
            LightShape::Rect { center, u, v, .. } => Some((center, u, v)),
            LightShape::Sphere { .. } => None,
        };
        RayPixels {
            ctx,
            tracer,
            sampler: LightSampler::new(l),
            pattern,
            prepared,
            rect,
        }
    }

    /// The samples of the pixel at `pixel` (receiver `g`): a rect light's
    /// stratified grid four at a time where [`sample_lanes`] applies, the
    /// same bits as [`LightSampler::samples_with`], which makes the others.
    fn draw_samples(&self, g: &GSample, pixel: (u32, u32), out: &mut Vec<LightSample>) {
        if let (LightSampler::Rect { center, u, v, area }, Some((strata, key))) =
            (self.sampler, self.pattern.jittered(pixel))
        {
            let n = self.pattern.len();
            if sample_lanes::rect_rows(strata, key, n, (center, u, v, area), out) {
                return;
            }
        }
        self.sampler
            .samples_with(&self.pattern, g.position, pixel, out);
    }

    /// Pixel `i`'s result from its samples' shadow rays (the reference's
    /// origin and test), resolved as the counting path resolves opaque
    /// counts in the direct mode: Vcoef = visible / N; the direct light 0
    /// when no sample is seen, the exact unshadowed integral when all are,
    /// else the samples' estimate with their visibilities. The depth
    /// complexity AOVs get what rays know: `dc_max` 1 where a sample is
    /// hidden, `dc_mean` the hidden fraction (lower bounds of the counts);
    /// `edges` 0.
    pub(super) fn pixel(&self, i: usize, scratch: &mut RayScratch) -> PixelResult {
        let gbuffer = self.ctx.gbuffer;
        let g: GSample = gbuffer.get(i).unwrap_or(GSample::BACKGROUND);
        if !g.is_surface() {
            return PixelResult::default();
        }
        // The tree's leaves in the region of every segment to the whole
        // light, before any sample is drawn: none, and the receiver is
        // lit by every sample, whichever are drawn (the result below for
        // `visible == n`, without drawing them); a few, and the rays are
        // tested against those only (the tracer skips the walk in runs
        // of shadowed receivers, where it finds too many).
        let known = match (self.rect, self.pattern.is_empty()) {
            (Some(rect), false) => self.tracer.light_hull(&g, rect, &mut scratch.tracer),
            _ => LightHull::Unknown,
        };
        if known == LightHull::Clear {
            let eye = self.ctx.view.eye.as_vec3();
            let point = surface_point(self.ctx.scene, &g, eye);
            return PixelResult {
                vcoef: 1.0,
                radiance: self.prepared.unshadowed_direct(&point),
                ..PixelResult::default()
            };
        }
        let width = (gbuffer.width as usize).max(1);
        let pixel = ((i % width) as u32, (i / width) as u32);
        self.draw_samples(&g, pixel, &mut scratch.samples);
        let n = scratch.samples.len();
        if n == 0 {
            // Inside a sphere light: no defined Vcoef (as the counting
            // path and the reference).
            return PixelResult {
                vcoef: 1.0,
                ..PixelResult::default()
            };
        }
        self.tracer.gsample_bundle(
            &g,
            &scratch.samples,
            self.rect,
            &mut scratch.vt,
            &mut scratch.tracer,
            known,
        );
        scratch.visibility.clear();
        scratch
            .visibility
            .extend(scratch.vt.iter().map(|&v| v as f32));
        // Visibilities of 0 and 1 (opaque casters only) sum exactly in
        // f32 in any order, as the counting path's count.
        let visible = scratch.visibility.iter().filter(|&&v| v > 0.0).count() as f32;
        let hidden = n as f32 - visible;
        let radiance = if visible == 0.0 {
            Vec3::ZERO
        } else {
            let eye = self.ctx.view.eye.as_vec3();
            let point = surface_point(self.ctx.scene, &g, eye);
            if visible == n as f32 {
                self.prepared.unshadowed_direct(&point)
            } else {
                self.prepared
                    .direct_from_samples(&point, &scratch.samples, &scratch.visibility)
            }
        };
        PixelResult {
            vcoef: visible / n as f32,
            radiance,
            max_dc: if hidden > 0.0 { 1.0 } else { 0.0 },
            mean_dc: hidden / n as f32,
            edges: 0.0,
            recounted: false,
        }
    }
}
