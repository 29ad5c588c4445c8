//! How every render runs a technique: the same checks and add-ons for all.

use super::kit::stsv;
use super::registry::Technique;
use super::technique::{check_scene, BuildParams, ShadowContext, ShadowOutput, Support};
use crate::error::Result;

/// Runs `technique` on `ctx` the way every render does: checks the scene
/// against its declared capabilities (refusing, or warning), computes it,
/// and applies the shared add-ons it declares (soft textured shadow
/// volumes for S-triangles).
pub fn run_technique(
    technique: Technique,
    params: &BuildParams,
    ctx: &ShadowContext,
) -> Result<ShadowOutput> {
    let warnings = check_scene(
        technique.info(),
        params.options,
        ctx.scene,
        ctx.geometry,
        ctx.view,
    )?;
    let built = technique.build(params);
    let mut out = built.compute(ctx)?;
    if technique.capabilities(params.options).s_triangles == Support::StsvAddOn {
        let sampling = stsv::StsvSampling {
            samples: params.samples,
            seed: params.seed,
            pattern: params.pattern,
            filter: params.options.stsv.opacity_filter,
        };
        stsv::addon::apply(ctx, technique.name(), sampling, &mut out)?;
    }
    out.warnings.extend(warnings);
    Ok(out)
}
