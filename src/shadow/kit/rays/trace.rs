//! The whole-light trace: one light's term over the G-buffer from the
//! tracer's rays. A child of `rays` (it reads the tracer's private state)
//! kept apart because it speaks the technique interface's types, which
//! the tracer itself, held by the shadow cache, must not import.

use super::{LightHull, Scratch, ShadowTracer};
use crate::sampling::{LightSampler, PatternSampler, SamplePattern};
use crate::scene::LightShape;
use crate::shade::{surface_point, PreparedLight};
use crate::shadow::technique::{LightTerm, ShadowContext};
use glam::Vec3;
use rayon::prelude::*;

impl ShadowTracer<'_> {
    /// One light's reference term over the whole G-buffer: Vcoef and the
    /// sampled radiance per pixel (0 for background; Vcoef 1 and radiance 0
    /// for a receiver inside a sphere light, which has no samples), and the
    /// BVH traversals it took. Rows run in parallel; each pixel's result
    /// depends only on its own samples, so the thread count never matters.
    /// `ctx` supplies the G-buffer and the eye; it must describe the scene
    /// the tracer was built for. The samples are stratified
    /// ([`ShadowTracer::trace_light_with`] with [`SamplePattern::Stratified`]).
    pub fn trace_light(
        &self,
        ctx: &ShadowContext,
        light_index: usize,
        n: u32,
        seed: u64,
    ) -> (LightTerm, u64) {
        let pattern = PatternSampler::new(SamplePattern::Stratified, n, seed, light_index);
        self.trace_light_with(ctx, light_index, &pattern)
    }

    /// [`ShadowTracer::trace_light`] with the samples of `pattern` (its
    /// `N` and seed; built for light `light_index`), mapped to the light
    /// by [`LightSampler::samples_with`].
    pub fn trace_light_with(
        &self,
        ctx: &ShadowContext,
        light_index: usize,
        pattern: &PatternSampler,
    ) -> (LightTerm, u64) {
        let gbuffer = ctx.gbuffer;
        let len = gbuffer.len();
        let mut vcoef = vec![0.0f32; len];
        let mut radiance = vec![Vec3::ZERO; len];
        let Some(light) = self.scene.lights.get(light_index) else {
            return (LightTerm::Radiance { radiance, vcoef }, 0);
        };
        let prepared = PreparedLight::new(light, &self.scene.textures);
        let sampler = LightSampler::new(light);
        let rect = match light.shape {
            LightShape::Rect { center, u, v, .. } => Some((center, u, v)),
            LightShape::Sphere { .. } => None,
        };
        let eye = ctx.view.eye.as_vec3();
        let width = (gbuffer.width as usize).max(1);
        let rays = vcoef
            .par_chunks_mut(width)
            .zip(radiance.par_chunks_mut(width))
            .enumerate()
            .map(|(y, (vrow, rrow))| {
                let mut samples = Vec::new();
                let mut vis = Vec::new();
                let mut vts = Vec::new();
                let mut scratch = Scratch::default();
                let mut rays = 0u64;
                if ctx.observer.cancelled() {
                    // The render discards a cancelled pass.
                    return rays;
                }
                for (x, (v, r)) in vrow.iter_mut().zip(rrow.iter_mut()).enumerate() {
                    let Some(g) = gbuffer.get(y * width + x) else {
                        continue;
                    };
                    if !g.is_surface() {
                        continue;
                    }
                    let pixel = (x as u32, y as u32);
                    sampler.samples_with(pattern, g.position, pixel, &mut samples);
                    if samples.is_empty() {
                        // Inside a sphere light: no defined Vcoef; 1 keeps
                        // images NaN-free (error figures leave it out).
                        *v = 1.0;
                        continue;
                    }
                    rays += self.gsample_bundle(
                        &g,
                        &samples,
                        rect,
                        &mut vts,
                        &mut scratch,
                        LightHull::Unknown,
                    );
                    // Sized once and written in place: with `push` (which
                    // may reallocate) the running sum went through memory
                    // on every sample.
                    vis.clear();
                    vis.resize(vts.len(), 0.0f32);
                    let mut sum = 0.0f64;
                    for (o, &vt) in vis.iter_mut().zip(&vts) {
                        sum += vt;
                        *o = vt as f32;
                    }
                    *v = (sum / samples.len() as f64) as f32;
                    *r = prepared.direct_from_samples(
                        &surface_point(self.scene, &g, eye),
                        &samples,
                        &vis,
                    );
                }
                rays
            })
            .sum();
        (LightTerm::Radiance { radiance, vcoef }, rays)
    }
}
