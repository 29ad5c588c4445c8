//! Soft textured shadow volumes as one add-on for every Vcoef technique
//! (thesis §5.2.1): S-triangles (opacity-textured casters) are not wedge
//! or shadow-volume casters; the add-on shadows them with their own
//! volumes, sampled like the reference, and subtracts their occluded
//! fraction from each light's Vcoef. The render applies it to every
//! technique whose capabilities declare [`Support::StsvAddOn`] for
//! S-triangles, the same way for all of them.
//!
//! [`Support::StsvAddOn`]: crate::shadow::technique::Support::StsvAddOn

use super::{occlusion_note, stsv_occlusion, StsvSampling};
use crate::error::Result;
use crate::output::Layer;
use crate::shadow::{LightTerm, ShadowContext, ShadowOutput};

/// Adds the S-triangles' occluded fraction `f` to a Vcoef technique's
/// result (thesis §5.2.1: the STSV Vcoef is added to the wedges' one):
/// `Vcoef = clamp(Vcoef − f, 0, 1)`. Pixels outside every STSV have
/// `f = 0` and keep their value bit for bit.
pub fn subtract_occlusion(vcoef: &mut [f32], occluded: &[f32]) {
    for (v, &f) in vcoef.iter_mut().zip(occluded) {
        if f > 0.0 {
            *v = (*v - f).clamp(0.0, 1.0);
        }
    }
}

/// Shadows the S-triangles of `ctx`'s scene into `out`, the result of
/// `technique`: per light, the occluded fraction is subtracted from its
/// Vcoef and becomes a channel of the `stsv` layer; the add-on's buffers
/// are noted. A scene without S-triangles gets only the note.
pub fn apply(
    ctx: &ShadowContext,
    technique: &str,
    sampling: StsvSampling,
    out: &mut ShadowOutput,
) -> Result<()> {
    let s_triangles = ctx.cache.s_triangles();
    let mut layer = Layer {
        name: "stsv".into(),
        channels: Vec::new(),
    };
    let mut stats = Vec::new();
    for (k, term) in out.lights.iter_mut().enumerate() {
        let stsv = stsv_occlusion(ctx, s_triangles, k, sampling, &mut out.passes)?;
        if let Some(stsv) = &stsv {
            if let LightTerm::Vcoef(vcoef) = term {
                subtract_occlusion(vcoef, &stsv.occluded);
            }
            layer.channels.push((k.to_string(), stsv.occluded.clone()));
        }
        stats.push(stsv.map(|s| (s.pairs, s.receivers)));
    }
    if !layer.channels.is_empty() {
        out.layers.push(layer);
    }
    out.buffers.push(occlusion_note(
        technique,
        s_triangles,
        sampling,
        &stats,
        ctx.gbuffer.len() as u64,
        rayon::current_num_threads() as u64,
    ));
    Ok(())
}
