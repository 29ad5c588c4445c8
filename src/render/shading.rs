//! The shading pass: ambient plus, per light, the unshadowed direct light
//! times the technique's visibility coefficient (or the technique's own
//! integrated radiance).

use crate::gbuffer::GBuffer;
use crate::scene::Scene;
use crate::shade::{surface_point, PreparedLight};
use crate::shadow::LightTerm;
use crate::view::View;
use glam::Vec3;
use rayon::prelude::*;

/// Radiance per pixel, row-major.
pub fn shade(scene: &Scene, view: &View, gbuffer: &GBuffer, terms: &[LightTerm]) -> Vec<Vec3> {
    let lights: Vec<PreparedLight> = scene
        .lights
        .iter()
        .map(|l| PreparedLight::new(l, &scene.textures))
        .collect();
    let eye = view.eye.as_vec3();
    let mut out = vec![scene.background; gbuffer.len()];
    out.par_chunks_mut(gbuffer.width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, radiance) in row.iter_mut().enumerate() {
                let i = y * gbuffer.width as usize + x;
                let g = gbuffer.sample(i);
                if !g.is_surface() {
                    continue;
                }
                let receives = scene.objects[g.object as usize].receive_shadows;
                let sp = surface_point(scene, &g, eye);
                let mut l = scene.ambient * g.albedo;
                for (light, term) in lights.iter().zip(terms) {
                    l += match term {
                        _ if !receives => light.unshadowed_direct(&sp),
                        LightTerm::Radiance { radiance, .. } => radiance[i],
                        LightTerm::Vcoef(v) if v[i] > 0.0 => light.unshadowed_direct(&sp) * v[i],
                        LightTerm::Vcoef(_) => Vec3::ZERO,
                    };
                }
                *radiance = l;
            }
        });
    out
}
