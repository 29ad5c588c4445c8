//! Caster groups: the sets of faces depth complexity sampling counts
//! separately because they attenuate light differently.
//!
//! - The **opaque** group (every opaque caster): its counter `D` decides
//!   binary visibility, `H(D) = [D ≤ 0]`.
//! - One **semi-opaque** group per distinct constant opacity `α`
//!   (`0 < α < 1`, no opacity texture): its counter `n` is the number of
//!   its surfaces a segment crosses, so its transmittance is `(1 − α)^n`.
//!
//! A semi-opaque group is counted with every face as an open, two-sided
//! layer (Bergeron's rule, as for open casters) even when its objects are
//! closed: the contract's transmittance multiplies `(1 − α)` once per
//! *surface crossed*, and that is exactly the number of layers the open
//! rule counts (a closed sphere crossed through is two layers, not one
//! volume).
//!
//! Why one integer counter per group rather than the thesis's float
//! multiply and divide per sample (algorithms 8–9): `T · (1−α) / (1−α)`
//! does not return `T` in floating point, loses everything at `α = 1`
//! (divide by 0) and drifts with many layers near `α = 1`. Integer counts
//! are exact whatever the order of the wedges; the float product is formed
//! once at the end, as `exp(Σ_g n_g · ln(1 − α_g))` with `ln(1 − α)` from
//! `ln_1p(−α)` (accurate for `α = 1e-7`, finite up to the largest `f32`
//! opacity below 1), so a sample crossing no semi-opaque surface gets
//! exactly `T = 1`.

use crate::geom::{EdgeAdjacency, SceneGeometry};
use crate::scene::Scene;
use std::collections::BTreeMap;

/// How a group's layers attenuate light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Attenuation {
    /// Any layer blocks the light.
    Opaque,
    /// Each layer transmits `1 − opacity`.
    Partial {
        /// The group's constant opacity, in `(0, 1)`.
        opacity: f64,
        /// `−ln(1 − opacity)` (> 0), the optical depth of one layer.
        optical_depth: f64,
    },
}

impl Attenuation {
    /// A semi-opaque layer of `opacity` in `(0, 1)`.
    pub fn partial(opacity: f64) -> Attenuation {
        Attenuation::Partial {
            opacity,
            optical_depth: -(-opacity).ln_1p(),
        }
    }
}

/// The semi-opaque casters of a scene: one adjacency per distinct
/// opacity, in increasing opacity order (deterministic), every face open.
/// Opacity-textured triangles are not here (they are S-triangles), nor
/// are fully transparent ones (`α = 0` casts nothing).
pub fn semi_opaque_groups(
    scene: &Scene,
    geometry: &SceneGeometry,
) -> Vec<(Attenuation, EdgeAdjacency)> {
    let opacity_of = |f: usize| -> Option<f32> {
        let object = scene.objects.get(geometry.triangle_object[f] as usize)?;
        let material = scene
            .materials
            .get(geometry.triangle_material[f] as usize)?;
        let partial = object.cast_shadows
            && material.opacity_texture.is_none()
            && material.opacity > 0.0
            && material.opacity < 1.0;
        partial.then_some(material.opacity)
    };
    // Keyed by the opacity's bits: positive floats order like their bits.
    let mut keys: BTreeMap<u32, f32> = BTreeMap::new();
    for f in 0..geometry.triangles.len() {
        if let Some(a) = opacity_of(f) {
            keys.insert(a.to_bits(), a);
        }
    }
    keys.into_values()
        .map(|a| {
            let mut adj = EdgeAdjacency::build(geometry, |f| {
                opacity_of(f as usize).is_some_and(|b| b.to_bits() == a.to_bits())
            });
            adj.face_closed.iter_mut().for_each(|c| *c = false);
            (Attenuation::partial(f64::from(a)), adj)
        })
        .filter(|(_, adj)| !adj.faces.is_empty())
        .collect()
}

/// Per-sample transmittance from the semi-opaque counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum TransmittanceMode {
    /// `T = Π_g (1 − α_g)^{n_g}`, the contract's product (stable form).
    #[default]
    Exact,
    /// The thesis's summed-opacity approximation (§4.3.3, for packed GPU
    /// counters): `T = max(0, 1 − Σ_g n_g α_g)`; right only under a single
    /// layer.
    Summed,
}

impl TransmittanceMode {
    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            TransmittanceMode::Exact => "exact",
            TransmittanceMode::Summed => "summed",
        }
    }

    /// What one layer of `attenuation` adds to the per-sample accumulator
    /// (optical depth, or summed opacity).
    pub fn per_layer(self, attenuation: Attenuation) -> f64 {
        match (self, attenuation) {
            (_, Attenuation::Opaque) => f64::INFINITY,
            (TransmittanceMode::Exact, Attenuation::Partial { optical_depth, .. }) => optical_depth,
            (TransmittanceMode::Summed, Attenuation::Partial { opacity, .. }) => opacity,
        }
    }

    /// The transmittance of an accumulated value.
    pub fn transmittance(self, accumulated: f64) -> f64 {
        match self {
            TransmittanceMode::Exact => (-accumulated).exp(),
            TransmittanceMode::Summed => (1.0 - accumulated).clamp(0.0, 1.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_compose_to_the_product() {
        for (a, n) in [
            (0.5f64, 100),
            (1e-7, 100),
            (0.999999, 3),
            (f64::from(1.0f32 - f32::EPSILON / 2.0), 2),
        ] {
            let at = Attenuation::partial(a);
            let acc = n as f64 * TransmittanceMode::Exact.per_layer(at);
            let t = TransmittanceMode::Exact.transmittance(acc);
            let product = (0..n).fold(1.0f64, |t, _| t * (1.0 - a));
            let rel = (t - product).abs() / product;
            assert!(rel < 1e-12, "α={a} n={n}: {t} vs {product}");
        }
        // No layer: exactly 1.
        assert_eq!(TransmittanceMode::Exact.transmittance(0.0), 1.0);
        assert_eq!(TransmittanceMode::Summed.transmittance(0.0), 1.0);
        // Summed saturates.
        let half = Attenuation::partial(0.5);
        let acc = 3.0 * TransmittanceMode::Summed.per_layer(half);
        assert_eq!(TransmittanceMode::Summed.transmittance(acc), 0.0);
    }
}
