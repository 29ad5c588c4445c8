//! A property test of agreement (issue 19): random small scenes — boxes,
//! spheres and quads, opaque and semi-opaque, under a rect or a sphere
//! light — through every registered technique at low resolution.
//!
//! - Exact techniques (declared `exact`) agree with the reference: same
//!   receivers, same light samples, so a pixel may differ only where a
//!   relation is a tie; at most [`EXACT_PIXELS`] of the surface pixels
//!   differ by more than [`EXACT_STEP`].
//! - Approximate techniques stay within [`APPROX_MEAN`] mean absolute Vcoef
//!   error of the reference, and where the reference is certain (a receiver
//!   fully lit or fully in umbra, every sample agreeing) they agree within
//!   0.5 on all but [`APPROX_WRONG_CERTAIN`] of those receivers — unless
//!   they declared that they ignore something in the scene (a warning;
//!   then only the next rule holds). Measured on 150 cases (seed 0x5eed):
//!   worst mean 0.19 (shadow-map: a hard shadow under a large light), worst
//!   wrong-certain fraction 2.3 % (shadow-map's bias at 32² maps' worth of
//!   receivers); DCS and the reference differ on no pixel.
//! - No technique produces a non-finite value; a refusal must be one of its
//!   declared capabilities.
//!
//! A failing case is shrunk (objects dropped, opacities made 1, the light
//! made smaller) while it still fails, and the minimal scene is printed as
//! a scene file. `PENUMBRA_AGREEMENT_CASES` (default 40) and
//! `PENUMBRA_AGREEMENT_SEED` run more or other cases.

use crate::common;

use common::Rng;
use penumbra::internal::render::{render, Aov, RenderOptions};
use penumbra::internal::shadow::technique::Support;
use penumbra::internal::shadow::{Technique, TechniqueOptions};

/// Image side of each case.
const SIZE: u32 = 32;
/// Light samples per pixel.
const SAMPLES: u32 = 16;
/// An exact technique's pixel counts as different beyond one sample's
/// weight at 16 samples.
const EXACT_STEP: f32 = 1.0 / 16.0 + 1e-4;
/// Fraction of surface pixels an exact technique may have different (ties).
const EXACT_PIXELS: f64 = 0.02;
/// Mean absolute Vcoef error bound of approximate techniques.
const APPROX_MEAN: f64 = 0.25;
/// Fraction of the reference's certain receivers an approximate technique
/// may get wrong by more than 0.5.
const APPROX_WRONG_CERTAIN: f64 = 0.05;

#[derive(Debug, Clone)]
struct Object {
    shape: &'static str,
    size: f64,
    at: [f64; 3],
    opacity: f64,
}

#[derive(Debug, Clone)]
struct Case {
    sphere_light: bool,
    light_size: f64,
    light_height: f64,
    objects: Vec<Object>,
}

impl Case {
    fn random(rng: &mut Rng) -> Case {
        let n = rng.range(1, 4) as usize;
        let objects = (0..n)
            .map(|_| Object {
                shape: ["box", "sphere", "quad"][rng.range(0, 2) as usize],
                size: 0.3 + rng.f64() * 1.2,
                at: [
                    rng.f64() * 3.0 - 1.5,
                    0.3 + rng.f64() * 2.0,
                    rng.f64() * 3.0 - 1.5,
                ],
                opacity: if rng.range(0, 3) == 0 { 0.5 } else { 1.0 },
            })
            .collect();
        Case {
            sphere_light: rng.range(0, 2) == 0,
            light_size: 0.1 + rng.f64() * 0.8,
            light_height: 3.5 + rng.f64() * 1.5,
            objects,
        }
    }

    fn toml(&self) -> String {
        let mut s = String::from(
            "[camera]\neye = [0.0, 5.0, 7.0]\ntarget = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\n\
             fov_y = 45.0\nwidth = 32\nheight = 32\n\n",
        );
        let h = self.light_height;
        if self.sphere_light {
            s += &format!(
                "[[light]]\ntype = \"sphere\"\ncenter = [0.0, {h}, 0.0]\nradius = {}\nradiance = [10.0, 10.0, 10.0]\n\n",
                self.light_size
            );
        } else {
            let a = self.light_size;
            s += &format!(
                "[[light]]\ntype = \"rect\"\ncenter = [0.0, {h}, 0.0]\nu = [{a}, 0.0, 0.0]\nv = [0.0, 0.0, {a}]\nradiance = [10.0, 10.0, 10.0]\n\n"
            );
        }
        s += "[[object]]\nname = \"ground\"\nshape = \"quad\"\nsize = [8.0, 8.0]\n\n";
        for (k, o) in self.objects.iter().enumerate() {
            let [x, y, z] = o.at;
            let size = match o.shape {
                "sphere" => format!("radius = {}", o.size / 2.0),
                "quad" => format!("size = [{0}, {0}]", o.size),
                _ => format!("size = [{0}, {0}, {0}]", o.size),
            };
            s += &format!(
                "[[object]]\nname = \"o{k}\"\nshape = \"{}\"\n{size}\ntranslate = [{x}, {y}, {z}]\nmaterial = {{ opacity = {} }}\n\n",
                o.shape, o.opacity
            );
        }
        s
    }

    /// Smaller cases that may still fail, simplest first.
    fn shrinks(&self) -> Vec<Case> {
        let mut out = Vec::new();
        for k in 0..self.objects.len() {
            if self.objects.len() > 1 {
                let mut c = self.clone();
                c.objects.remove(k);
                out.push(c);
            }
        }
        for k in 0..self.objects.len() {
            if self.objects[k].opacity != 1.0 {
                let mut c = self.clone();
                c.objects[k].opacity = 1.0;
                out.push(c);
            }
        }
        if self.light_size > 0.15 {
            let mut c = self.clone();
            c.light_size = (self.light_size / 2.0).max(0.1);
            out.push(c);
        }
        out
    }
}

/// What went wrong with one technique on one case, or `None`.
fn check(case: &Case, technique: Technique, reference: &[f32], mask: &[bool]) -> Option<String> {
    let scene = common::scene_in_scratch("agreement", &case.toml(), &[]);
    let defaults = TechniqueOptions::default();
    let caps = technique.capabilities(&defaults);
    let out = match render(&scene, &options(technique)) {
        Ok(out) => out,
        Err(e) => {
            let e = e.to_string();
            let declared = [caps.sphere_lights, caps.enclosed_lights, caps.semi_opaque]
                .iter()
                .any(|s| matches!(s, Support::Refused { .. }));
            return (!declared).then(|| format!("refused without a declared reason: {e}"));
        }
    };
    let v = out.lights[0].vcoef();
    if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
        return Some(format!("non-finite Vcoef {bad}"));
    }
    if !out.warnings.is_empty() || technique.name() == "none" {
        return None; // it said what it leaves out; only finiteness holds
    }
    let surface = mask.iter().filter(|&&m| m).count().max(1) as f64;
    let (mut sum, mut differing) = (0.0f64, 0usize);
    for ((a, b), &m) in v.iter().zip(reference).zip(mask) {
        if m {
            let d = (a - b).abs();
            sum += f64::from(d);
            differing += usize::from(d > EXACT_STEP);
        }
    }
    let (mean, frac) = (sum / surface, differing as f64 / surface);
    // Receivers the reference sees fully lit or fully in umbra.
    let certain: Vec<(f32, f32)> = v
        .iter()
        .zip(reference)
        .zip(mask)
        .filter(|((_, &b), &m)| m && (b == 0.0 || b == 1.0))
        .map(|((&a, &b), _)| (a, b))
        .collect();
    let wrong_certain = certain.iter().filter(|(a, b)| (a - b).abs() > 0.5).count() as f64
        / certain.len().max(1) as f64;
    if std::env::var_os("PENUMBRA_AGREEMENT_STATS").is_some() {
        println!(
            "STATS {} mean {mean:.4} differing {frac:.4} wrong-certain {wrong_certain:.4}",
            technique.name()
        );
    }
    if caps.exact && frac > EXACT_PIXELS {
        return Some(format!(
            "exact, but {:.2} % of pixels differ (mean {mean:.4})",
            frac * 100.0
        ));
    }
    if !caps.exact && mean > APPROX_MEAN {
        return Some(format!("mean absolute error {mean:.4} > {APPROX_MEAN}"));
    }
    if !caps.exact && wrong_certain > APPROX_WRONG_CERTAIN {
        return Some(format!(
            "{:.2} % of the fully lit or umbra receivers wrong by more than 0.5",
            wrong_certain * 100.0
        ));
    }
    None
}

/// The run of `technique`, with the sampling under which an exact
/// technique's samples are the reference's ([`common::matched_sampling`]);
/// the reference it is held against is rendered with the same pattern.
fn options(technique: Technique) -> RenderOptions {
    let (options, pattern) = common::matched_sampling(technique);
    RenderOptions {
        technique,
        samples: SAMPLES,
        width: Some(SIZE),
        height: Some(SIZE),
        pattern,
        options,
        ..RenderOptions::default()
    }
}

/// The failure of `technique` on `case`, if any, with the reference's
/// result computed here.
fn failure(case: &Case, technique: Technique) -> Option<String> {
    let scene = common::scene_in_scratch("agreement-ref", &case.toml(), &[]);
    let mut ref_options = options(technique);
    ref_options.technique = Technique::named("reference").unwrap();
    ref_options.aovs = vec![Aov::Mask];
    let reference =
        render(&scene, &ref_options).expect("the reference renders every generated scene");
    let v = reference.lights[0].vcoef();
    assert!(v.iter().all(|x| x.is_finite()), "reference non-finite");
    let mask_layer = reference
        .layers
        .iter()
        .find(|l| l.name == "mask")
        .expect("mask AOV");
    let mask: Vec<bool> = mask_layer.channels[0].1.iter().map(|&m| m > 0.5).collect();
    check(case, technique, v, &mask)
}

#[test]
fn every_technique_agrees_with_the_reference_on_random_small_scenes() {
    let cases: u64 = std::env::var("PENUMBRA_AGREEMENT_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(40);
    let seed: u64 = std::env::var("PENUMBRA_AGREEMENT_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed);
    let mut failures = Vec::new();
    for c in 0..cases {
        let mut rng = Rng(seed ^ c.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let case = Case::random(&mut rng);
        for t in Technique::all() {
            let Some(mut why) = failure(&case, t) else {
                continue;
            };
            // Shrink: take the first smaller case that still fails, until
            // none does.
            let mut minimal = case.clone();
            'shrink: loop {
                for smaller in minimal.shrinks() {
                    if let Some(w) = failure(&smaller, t) {
                        minimal = smaller;
                        why = w;
                        continue 'shrink;
                    }
                }
                break;
            }
            failures.push(format!(
                "case {c} (seed {seed:#x}), {}: {why}\nminimal scene:\n{}",
                t.name(),
                minimal.toml()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failure(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}
