//! The instruction-set level hot code runs at, chosen once at run time.
//!
//! A build for plain x86-64 (what `cargo build` makes, and what runs on
//! any x86-64 CPU) leaves most of a modern CPU unused: no `popcnt`,
//! `tzcnt` or `blsr` for the walks' lane masks, no three-operand VEX
//! forms. A hot routine can therefore be compiled twice, its body an
//! `#[inline(always)]` function called once from a plain wrapper and once
//! from a `#[target_feature(enable = "avx,avx2,bmi1,bmi2,lzcnt,popcnt")]`
//! wrapper (the x86-64-v3 features that change no arithmetic: no FMA),
//! and pick the copy by [`level`]. (A shared `run_at(level, || body())`
//! with one generic `target_feature` wrapper was measured and dropped:
//! LLVM did not inline the closure into it, so the "v3" copy ran the
//! baseline body through a call, +13 % instructions on the reference's
//! light pass; hence one explicit wrapper per routine.) Both copies are the same Rust code on
//! the facade's lane types, whose every operation is a fixed IEEE
//! operation, and Rust never contracts `a * b + c` into a fused
//! multiply-add, so the copies give the same bits; each routine's tests
//! run both and compare.
//!
//! `PENUMBRA_SIMD=baseline` in the environment forces the plain copies
//! (and no AVX kernel, [`super::avx`]), so one binary can be checked
//! at both levels; `PENUMBRA_SIMD=v3` insists on the v3 copies and is
//! an error on a CPU without them. [`check_env`] reports a bad value.

use std::sync::OnceLock;

/// An instruction-set level of the run-time-dispatched routines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// The features the build targets, nothing more.
    Baseline,
    /// x86-64-v3's AVX, AVX2, BMI1, BMI2, LZCNT and POPCNT (no FMA).
    V3,
}

impl Level {
    /// Whether this CPU can run code compiled for the level.
    pub fn supported(self) -> bool {
        match self {
            Level::Baseline => true,
            Level::V3 => v3_supported(),
        }
    }

    /// The level's name, as `PENUMBRA_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Level::Baseline => "baseline",
            Level::V3 => "v3",
        }
    }
}

/// Whether the CPU has every feature of [`Level::V3`] (checked once).
fn v3_supported() -> bool {
    static V3: OnceLock<bool> = OnceLock::new();
    *V3.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            std::is_x86_feature_detected!("avx")
                && std::is_x86_feature_detected!("avx2")
                && std::is_x86_feature_detected!("bmi1")
                && std::is_x86_feature_detected!("bmi2")
                && std::is_x86_feature_detected!("lzcnt")
                && std::is_x86_feature_detected!("popcnt")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    })
}

/// The level `PENUMBRA_SIMD` asks for: `Ok(None)` when it is unset or
/// empty (pick the best), an error naming the variable for an unknown
/// value or a level this CPU lacks.
pub fn from_env() -> Result<Option<Level>, String> {
    let Some(value) = std::env::var_os("PENUMBRA_SIMD") else {
        return Ok(None);
    };
    let value = value.to_string_lossy();
    let level = match value.trim() {
        "" => return Ok(None),
        "baseline" => Level::Baseline,
        "v3" => Level::V3,
        other => {
            return Err(format!(
                "{other:?}: expected \"baseline\" or \"v3\" (or unset for the best this CPU has)"
            ))
        }
    };
    if !level.supported() {
        return Err("\"v3\": this CPU lacks one of AVX, AVX2, BMI1, BMI2, LZCNT, POPCNT".into());
    }
    Ok(Some(level))
}

/// Checks `PENUMBRA_SIMD` (the command line calls this first, so a bad
/// value is an error, not a silent fallback).
pub fn check_env() -> Result<(), String> {
    from_env().map(|_| ())
}

/// The level the dispatched routines run at: `PENUMBRA_SIMD`'s, else the
/// best this CPU supports (decided once per process; an invalid
/// `PENUMBRA_SIMD`, which [`check_env`] reports, counts as unset).
pub fn level() -> Level {
    static LEVEL: OnceLock<Level> = OnceLock::new();
    *LEVEL.get_or_init(|| match from_env() {
        Ok(Some(level)) => level,
        _ if v3_supported() => Level::V3,
        _ => Level::Baseline,
    })
}

/// Whether the x86-64-v3 copies run: [`level`] is v3 and this CPU has
/// every feature of the level (checked at run time, the one requirement
/// of each v3 copy's `target_feature` call). One cached flag for the hot
/// dispatch sites.
#[inline]
pub fn runs_v3() -> bool {
    static V3: OnceLock<bool> = OnceLock::new();
    *V3.get_or_init(|| level() == Level::V3 && Level::V3.supported())
}

/// One line for `--explain`: the level the dispatched routines run at,
/// whether the AVX kernels run, and the features the build itself targets.
pub fn describe() -> String {
    let level = level();
    let features = match level {
        Level::Baseline => "the build's own features",
        Level::V3 => "AVX, AVX2, BMI1, BMI2, LZCNT, POPCNT",
    };
    let built = if cfg!(target_feature = "avx512f") {
        "AVX-512"
    } else if cfg!(target_feature = "avx2") {
        "AVX2"
    } else if cfg!(target_feature = "sse4.2") {
        "SSE4.2"
    } else {
        "baseline"
    };
    format!(
        "dispatched routines at {} ({features}), AVX kernels {}, build targets {built}",
        level.name(),
        if super::avx::available() { "on" } else { "off" },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn baseline_is_always_supported_and_the_level_is() {
        assert!(Level::Baseline.supported());
        assert!(level().supported());
        assert_eq!(Level::V3.name(), "v3");
    }
}
