//! `--verify` for a technique picked from the registry: builds it, checks
//! that it exposes its per-sample decisions, and hands them to the kit's
//! certificate ([`super::kit::verify`]), which knows no technique.

use super::kit::verify::{verify_all, verify_with, VerifyReport, EVERY_RELATION, MAX_RELATIONS};
use super::options::TechniqueOptions;
use super::registry::Technique;
use super::technique::{BuildParams, ShadowContext};
use crate::error::{Error, Result};

/// The names of the techniques that expose their decisions.
pub fn verifiable() -> Vec<&'static str> {
    let options = TechniqueOptions::default();
    let params = BuildParams {
        samples: 1,
        seed: 0,
        pattern: Default::default(),
        options: &options,
    };
    Technique::all()
        .filter(|t| t.build(&params).sample_decisions().is_some())
        .map(|t| t.name())
        .collect()
}

/// An error unless `technique` built from `params` exposes its decisions
/// and `k` is in `1..=MAX_RELATIONS` or [`EVERY_RELATION`].
pub fn check_verifiable(technique: Technique, params: &BuildParams, k: u64) -> Result<()> {
    if !(1..=MAX_RELATIONS).contains(&k) && k != EVERY_RELATION {
        return Err(Error::param(
            "--verify",
            format!("{k} relations is outside 1..={MAX_RELATIONS}"),
        ));
    }
    if technique.build(params).sample_decisions().is_some() {
        return Ok(());
    }
    Err(Error::param(
        "--verify",
        format!(
            "`{}` does not expose its per-sample decisions, so it cannot be verified \
             (verifiable: {})",
            technique.name(),
            verifiable().join(", ")
        ),
    ))
}

/// Checks `k` relations of `technique` (built from `params`) on `ctx`.
/// The technique's light passes run again through its
/// [`SampleDecisions`](crate::shadow::technique::SampleDecisions) (deterministic: the render's own decisions).
pub fn verify(
    technique: Technique,
    params: &BuildParams,
    ctx: &ShadowContext,
    k: u64,
) -> Result<VerifyReport> {
    check_verifiable(technique, params, k)?;
    let built = technique.build(params);
    let Some(decisions) = built.sample_decisions() else {
        return Err(Error::param(
            "--verify",
            format!("{} has no per-sample decisions to verify", technique.name()),
        ));
    };
    let exact = technique.capabilities(params.options).exact;
    if k == EVERY_RELATION {
        return verify_all(decisions, technique.name(), exact, ctx, params.samples);
    }
    verify_with(decisions, technique.name(), exact, ctx, k, params.seed)
}
