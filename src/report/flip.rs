//! FLIP: NVlabs' perceptual error between a reference and a test image
//! (Andersson et al., HPG 2020), through `nv-flip`, the binding of NVlabs'
//! own C++ implementation.
//!
//! FLIP is measured on display-referred images, as users see them: linear
//! radiance is tone-mapped exactly as the PNG output is ([`srgb8`]: clamped
//! to [0, 1], NaN as 0, the exact sRGB curve, 8-bit codes), and LDR-FLIP
//! compares the two at [`FLIP_PPD`] pixels per degree (NVlabs' default: a
//! 0.7 m wide 4K monitor seen from 0.7 m). The result is a per-pixel error
//! map in [0, 1], pooled into a mean and percentiles ([`FlipMetrics`]),
//! over the whole frame or any subset of its pixels (e.g. the interior,
//! [`super::interior`]).

use super::heatmap::{write_with_colour_bar, HeatmapScale};
use crate::error::{Error, Result};
use crate::output::srgb8;
use glam::Vec3;
use serde::Serialize;
use std::path::Path;

/// Pixels per degree of visual angle FLIP is computed at:
/// `nv_flip::DEFAULT_PIXELS_PER_DEGREE` (67).
pub const FLIP_PPD: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// The colour scale of FLIP error maps: FLIP's own range, 0 (no visible
/// difference) to 1, unitless.
pub const FLIP_SCALE: HeatmapScale<'static> = HeatmapScale {
    quantity: "FLIP error",
    unit: "unitless, 0 to 1",
    max: 1.0,
};

/// The percentiles [`FlipMetrics`] reports.
pub const FLIP_PERCENTILES: [f64; 3] = [0.5, 0.9, 0.99];

/// A FLIP error map pooled over a set of pixels.
///
/// The mean is summed in `f64` in pixel order (the same bits every run);
/// the percentiles are FLIP's own pooling (`FlipPool::get_percentile`
/// unweighted: the nearest-rank value of the sorted errors); the maximum is
/// the largest value. An empty set gives zeros.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct FlipMetrics {
    /// Pixels pooled.
    pub count: u64,
    /// Mean FLIP error (NVlabs' recommended single number).
    pub mean: f64,
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest error.
    pub max: f64,
}

/// FLIP over the whole frame and over its interior (pixels away from
/// geometric edges, [`super::interior`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct FlipRegions {
    /// Every pixel of the frame.
    pub all: FlipMetrics,
    /// Interior pixels only.
    pub interior: FlipMetrics,
}

/// A FLIP error map: one value in [0, 1] per pixel, row-major, row 0 at
/// the top.
#[derive(Debug, Clone, PartialEq)]
pub struct FlipMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The errors.
    pub values: Vec<f32>,
}

/// The FLIP error map of `test` against `reference`, both 8-bit sRGB
/// (`width × height × 3` codes, as [`srgb8`] gives). `None` for an empty
/// image or sizes that do not match (callers check sizes first and say
/// which image is at fault).
pub fn flip_rgb8(reference: &[u8], test: &[u8], width: u32, height: u32) -> Option<FlipMap> {
    let n = width as usize * height as usize * 3;
    if n == 0 || reference.len() != n || test.len() != n {
        return None;
    }
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    let map = nv_flip::flip(r, t, FLIP_PPD);
    Some(FlipMap {
        width,
        height,
        values: map.to_vec(),
    })
}

/// The FLIP error map of linear radiance `test` against `reference`,
/// both tone-mapped as the PNG output is ([`srgb8`]).
pub fn flip_radiance(
    reference: &[Vec3],
    test: &[Vec3],
    width: u32,
    height: u32,
) -> Option<FlipMap> {
    flip_rgb8(&srgb8(reference), &srgb8(test), width, height)
}

impl FlipMap {
    /// The map pooled over the pixels where `include(i)` holds.
    pub fn metrics(&self, include: impl Fn(usize) -> bool) -> FlipMetrics {
        let values: Vec<f32> = (self.values.iter().enumerate())
            .filter(|&(i, _)| include(i))
            .map(|(_, &v)| v)
            .collect();
        pool(&values)
    }

    /// The map pooled over every pixel.
    pub fn metrics_all(&self) -> FlipMetrics {
        pool(&self.values)
    }

    /// The map pooled over the whole frame and over `interior`.
    pub fn regions(&self, interior: &[bool]) -> FlipRegions {
        FlipRegions {
            all: self.metrics_all(),
            interior: self.metrics(|i| interior.get(i).copied().unwrap_or(false)),
        }
    }

    /// The map through FLIP's magma colour map (`nv_flip::magma_lut`, as
    /// NVlabs' tool shows it), 8-bit RGB.
    pub fn magma_rgb8(&self) -> Vec<u8> {
        let map = nv_flip::FlipImageFloat::with_data(self.width, self.height, &self.values);
        map.apply_color_lut(&nv_flip::magma_lut()).to_vec()
    }

    /// Writes the map through the magma colour map as an 8-bit RGB PNG at
    /// `path`, atomically (as every PNG here), with its colour bar under
    /// it ([`FLIP_SCALE`], [`super::heatmap::write_with_colour_bar`]):
    /// the PNG is [`super::heatmap::heatmap_canvas`] of the map's size.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        if self.values.len() != self.width as usize * self.height as usize {
            return Err(Error::file(path, None, "the FLIP map has the wrong size"));
        }
        let lut = nv_flip::magma_lut().to_vec();
        let magma = |t: f64| -> [u8; 3] {
            let i = (t.clamp(0.0, 1.0) * 255.0).round() as usize * 3;
            match lut.get(i..i + 3) {
                Some(c) => [c[0], c[1], c[2]],
                None => [0, 0, 0],
            }
        };
        write_with_colour_bar(
            path,
            self.width,
            self.height,
            &self.magma_rgb8(),
            &magma,
            &FLIP_SCALE,
            &[],
        )
    }
}

/// Pools `values` with FLIP's own pooling (a one-row image of them, so the
/// same code pools a whole frame and any subset), the mean in `f64`.
fn pool(values: &[f32]) -> FlipMetrics {
    if values.is_empty() {
        return FlipMetrics::default();
    }
    let count = values.len() as u64;
    let mean = values.iter().map(|&v| f64::from(v)).sum::<f64>() / count as f64;
    let Ok(width) = u32::try_from(values.len()) else {
        // Over 4 G pixels: no such image fits in memory here anyway.
        return FlipMetrics {
            count,
            mean,
            ..FlipMetrics::default()
        };
    };
    let row = nv_flip::FlipImageFloat::with_data(width, 1, values);
    let mut pool = nv_flip::FlipPool::from_image(&row);
    let [p50, p90, p99] = FLIP_PERCENTILES.map(|p| f64::from(pool.get_percentile(p as f32, false)));
    // Our own maximum: FLIP's pool starts its maximum at the smallest
    // positive float (`numeric_limits<float>::min()`), so an all-zero map
    // would report 1.2e-38.
    let max = values.iter().fold(0.0f32, |m, &v| m.max(v));
    FlipMetrics {
        count,
        mean,
        p50,
        p90,
        p99,
        max: f64::from(max),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooling_a_subset_is_pooling_its_values() {
        let values: Vec<f32> = (0..1000).map(|i| (i as f32 / 999.0).powi(3)).collect();
        let map = FlipMap {
            width: 50,
            height: 20,
            values: values.clone(),
        };
        let all = map.metrics_all();
        assert_eq!(all.count, 1000);
        assert_eq!(all.max, 1.0);
        // Nearest rank: the value at ceil(n p) of the sorted values.
        assert_eq!(all.p50, f64::from(values[500]));
        assert_eq!(all.p90, f64::from(values[900]));
        assert_eq!(all.p99, f64::from(values[990]));
        let even = map.metrics(|i| i % 2 == 0);
        assert_eq!(even.count, 500);
        assert_eq!(even.p50, f64::from(values[500]));
        assert_eq!(map.metrics(|_| false), FlipMetrics::default());
        // FLIP's own mean (an f32 sum) agrees with ours.
        let row = nv_flip::FlipImageFloat::with_data(1000, 1, &values);
        let theirs = nv_flip::FlipPool::from_image(&row).mean();
        assert!(
            (f64::from(theirs) - all.mean).abs() < 1e-5,
            "{theirs} {all:?}"
        );
    }

    #[test]
    fn mismatched_sizes_are_refused() {
        assert!(flip_rgb8(&[0; 12], &[0; 12], 2, 2).is_some());
        assert!(flip_rgb8(&[0; 12], &[0; 9], 2, 2).is_none());
        assert!(flip_rgb8(&[], &[], 0, 0).is_none());
    }
}
