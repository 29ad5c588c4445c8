//! `penumbra diff`: error metrics between two images, channel by channel,
//! optionally under a mask, checked against tolerances; with `--flip`,
//! FLIP between their colours too ([`super::flip`]).

use super::flip::{flip_radiance, FlipMetrics, FLIP_PPD};
use super::metrics::{ErrorAccumulator, ErrorMetrics};
use crate::error::{Error, Result};
use crate::output::{check_not_input, image_format, read_image, Format, LoadedImage};
use glam::Vec3;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to compare and what to accept.
#[derive(Debug, Clone, Default)]
pub struct DiffOptions {
    /// Channels of image A, paired by position with `channels_b`. Both
    /// empty: the channels the images share, in A's order. One empty: the
    /// same names on both sides.
    pub channels_a: Vec<String>,
    /// Channels of image B (see `channels_a`).
    pub channels_b: Vec<String>,
    /// An image of the same size; only pixels where its mask channel is
    /// above 0.5 are compared.
    pub mask: Option<PathBuf>,
    /// The mask's channel; by default `mask.Y`, else `Y`, else `R`, else
    /// its first channel.
    pub mask_channel: Option<String>,
    /// Fail when any channel's largest absolute error exceeds this.
    pub max_abs: Option<f64>,
    /// Fail when the RMSE over all compared channels exceeds this.
    pub rmse: Option<f64>,
    /// Also measure FLIP between the images' colours (`R, G, B` of both,
    /// tone-mapped as the PNG output is; A is the test, B the reference),
    /// pooled over the mask's pixels when there is a mask.
    pub flip: bool,
    /// Fail when the FLIP mean exceeds this (implies `flip`).
    pub flip_threshold: Option<f64>,
    /// Write the FLIP error map here, a PNG in FLIP's magma colours
    /// (implies `flip`); never over an input.
    pub flip_map: Option<PathBuf>,
}

impl DiffOptions {
    /// FLIP is measured (asked for, or needed by a threshold or a map).
    pub fn wants_flip(&self) -> bool {
        self.flip || self.flip_threshold.is_some() || self.flip_map.is_some()
    }
}

/// FLIP between the images of a [`diff_images`].
#[derive(Debug, Clone, Serialize)]
pub struct FlipDiff {
    /// The error map pooled over the compared pixels (every pixel, or the
    /// mask's).
    pub metrics: FlipMetrics,
    /// Pooled under the mask.
    pub masked: bool,
    /// Pixels per degree it was computed at.
    pub pixels_per_degree: f32,
    /// `R, G, B` values that were NaN or infinite in either image (the
    /// tone mapping makes them 0 or 1, so FLIP alone would not tell).
    pub non_finite: u64,
}

/// The metrics of one channel pair.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelDiff {
    /// The channel's name in image A.
    pub channel_a: String,
    /// The channel's name in image B.
    pub channel_b: String,
    /// `A − B` statistics over the compared pixels.
    pub metrics: ErrorMetrics,
}

/// The result of [`diff_images`].
#[derive(Debug, Clone, Serialize)]
pub struct DiffReport {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// One entry per compared channel pair, in the order compared.
    pub channels: Vec<ChannelDiff>,
    /// All channels' values together.
    pub overall: ErrorMetrics,
    /// FLIP, when asked for.
    pub flip: Option<FlipDiff>,
    /// Each exceeded tolerance, in words; empty when the diff passes.
    pub failures: Vec<String>,
}

impl DiffReport {
    /// No tolerance was exceeded.
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// A table for the terminal (one line per channel and one for all of
    /// them), then `PASS`, or one `FAIL:` line per failure.
    pub fn to_text(&self) -> String {
        let mut rows: Vec<[String; 7]> = vec![[
            "channel".into(),
            "count".into(),
            "rmse".into(),
            "mean abs".into(),
            "max abs".into(),
            "% > 1/255".into(),
            "non-finite".into(),
        ]];
        let row = |name: String, m: &ErrorMetrics| {
            [
                name,
                m.count.to_string(),
                short(m.rmse),
                short(m.mean_abs),
                short(m.max_abs),
                format!("{:.2}", 100.0 * m.frac_over),
                m.non_finite.to_string(),
            ]
        };
        for c in &self.channels {
            rows.push(row(pair_name(c), &c.metrics));
        }
        if self.channels.len() > 1 {
            rows.push(row("all".into(), &self.overall));
        }
        let mut widths = [0usize; 7];
        for r in &rows {
            for (w, cell) in widths.iter_mut().zip(r) {
                *w = (*w).max(cell.chars().count());
            }
        }
        let mut out = format!("{}×{} pixels\n", self.width, self.height);
        for r in &rows {
            let mut line = format!("{:<w$}", r[0], w = widths[0]);
            for (cell, w) in r.iter().zip(widths).skip(1) {
                let _ = write!(line, "  {cell:>w$}");
            }
            out.push_str(line.trim_end());
            out.push('\n');
        }
        if let Some(f) = &self.flip {
            let m = &f.metrics;
            let _ = writeln!(
                out,
                "FLIP (sRGB 8-bit, {} ppd) over {} pixels{}: mean {}  p50 {}  p90 {}  p99 {}  max {}{}",
                f.pixels_per_degree,
                m.count,
                if f.masked { " under the mask" } else { "" },
                short(m.mean),
                short(m.p50),
                short(m.p90),
                short(m.p99),
                short(m.max),
                match f.non_finite {
                    0 => String::new(),
                    n => format!("  ({n} non-finite R, G, B values)"),
                }
            );
        }
        if self.passed() {
            out.push_str("PASS\n");
        } else {
            for f in &self.failures {
                let _ = writeln!(out, "FAIL: {f}");
            }
        }
        out
    }
}

/// `R`, or `vcoef.0 / light0` when the two sides' names differ.
fn pair_name(c: &ChannelDiff) -> String {
    if c.channel_a == c.channel_b {
        c.channel_a.clone()
    } else {
        format!("{} / {}", c.channel_a, c.channel_b)
    }
}

/// `: 2 non-finite values` when there are any: why an error is infinite.
fn non_finite_note(m: &ErrorMetrics) -> String {
    match m.non_finite {
        0 => String::new(),
        1 => ": 1 non-finite value".into(),
        n => format!(": {n} non-finite values"),
    }
}

/// A number with about four significant digits, for people.
fn short(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-4..1e6).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 8) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.3e}")
    }
}

/// Compares image `a` (the test) with image `b` (the reference): see
/// [`DiffOptions`] for the channels, mask and tolerances.
///
/// Errors name the file or the option at fault: unreadable images, sizes
/// that differ, channels an image lacks, a bad tolerance, a mask channel
/// without a mask.
pub fn diff_images(a: &Path, b: &Path, options: &DiffOptions) -> Result<DiffReport> {
    check_options(a, b, options)?;
    let (image_a, image_b) = read_pair(a, b)?;
    let pairs = channel_pairs(a, &image_a, b, &image_b, options)?;
    let mask = match &options.mask {
        Some(path) => Some(load_mask(path, options.mask_channel.as_deref(), &image_a)?),
        None => None,
    };
    let (channels, overall) = channel_errors(&image_a, &image_b, pairs, mask.as_deref());
    let flip = match options.wants_flip() {
        true => Some(flip_diff(
            (a, &image_a),
            (b, &image_b),
            mask.as_deref(),
            options,
        )?),
        false => None,
    };
    let failures = failures(options, &channels, &overall, flip.as_ref());
    Ok(DiffReport {
        width: image_a.width,
        height: image_a.height,
        channels,
        overall,
        flip,
        failures,
    })
}

/// The tolerances are numbers, a mask channel has its mask, and the FLIP
/// map is a PNG that is no input.
fn check_options(a: &Path, b: &Path, options: &DiffOptions) -> Result<()> {
    for (name, tolerance) in [
        ("--max-abs", options.max_abs),
        ("--rmse", options.rmse),
        ("--flip-threshold", options.flip_threshold),
    ] {
        if let Some(t) = tolerance {
            if !(t >= 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be a non-negative number, got {t}"),
                ));
            }
        }
    }
    if options.mask.is_none() && options.mask_channel.is_some() {
        return Err(Error::param(
            "--mask-channel",
            "picks a channel of the mask image, so it needs --mask",
        ));
    }
    // The map is checked before any work, and never written over an input.
    if let Some(map) = &options.flip_map {
        if image_format("--flip-map", map)? != Format::Png {
            return Err(Error::param(
                "--flip-map",
                format!(
                    "{}: the error map is an 8-bit PNG in FLIP's magma colours; give a .png path",
                    map.display()
                ),
            ));
        }
        let mut inputs = vec![a.to_path_buf(), b.to_path_buf()];
        inputs.extend(options.mask.clone());
        check_not_input(map, &inputs)?;
    }
    Ok(())
}

/// Both images, of one size.
fn read_pair(a: &Path, b: &Path) -> Result<(LoadedImage, LoadedImage)> {
    let image_a = read_image(a)?;
    let image_b = read_image(b)?;
    if (image_a.width, image_a.height) != (image_b.width, image_b.height) {
        return Err(Error::file(
            b,
            None,
            format!(
                "is {}×{} but {} is {}×{}; diff compares images of one size",
                image_b.width,
                image_b.height,
                a.display(),
                image_a.width,
                image_a.height
            ),
        ));
    }
    Ok((image_a, image_b))
}

/// Per channel pair, and over all of them, the error metrics of the
/// pixels under `mask` (all without one).
fn channel_errors(
    image_a: &LoadedImage,
    image_b: &LoadedImage,
    pairs: Vec<(String, String)>,
    mask: Option<&[f32]>,
) -> (Vec<ChannelDiff>, ErrorMetrics) {
    let mut overall = ErrorAccumulator::default();
    let mut channels = Vec::with_capacity(pairs.len());
    for (name_a, name_b) in pairs {
        // Present: `channel_pairs` checked every name.
        let (Some(va), Some(vb)) = (image_a.channel(&name_a), image_b.channel(&name_b)) else {
            continue;
        };
        let mut acc = ErrorAccumulator::default();
        for (i, (&x, &y)) in va.iter().zip(vb).enumerate() {
            if mask
                .as_ref()
                .is_none_or(|m| m.get(i).is_some_and(|v| *v > 0.5))
            {
                acc.add(f64::from(x), f64::from(y));
            }
        }
        overall.merge(&acc);
        channels.push(ChannelDiff {
            channel_a: name_a,
            channel_b: name_b,
            metrics: acc.finish(),
        });
    }
    (channels, overall.finish())
}

/// FLIP of `a`'s colours (the test image) against `b`'s (the reference),
/// each a path and its image, over the pixels under `mask`; writes the
/// map when asked.
fn flip_diff(
    (a, image_a): (&Path, &LoadedImage),
    (b, image_b): (&Path, &LoadedImage),
    mask: Option<&[f32]>,
    options: &DiffOptions,
) -> Result<FlipDiff> {
    let (test, bad_a) = colours(a, image_a)?;
    let (reference, bad_b) = colours(b, image_b)?;
    let (w, h) = (image_a.width, image_a.height);
    let map = flip_radiance(&reference, &test, w, h)
        .ok_or_else(|| Error::file(a, None, "an empty image has no FLIP"))?;
    let metrics = match mask {
        Some(m) => map.metrics(|i| m.get(i).is_some_and(|v| *v > 0.5)),
        None => map.metrics_all(),
    };
    if let Some(path) = &options.flip_map {
        map.write_png(path)?;
    }
    Ok(FlipDiff {
        metrics,
        masked: mask.is_some(),
        pixels_per_degree: FLIP_PPD,
        non_finite: bad_a + bad_b,
    })
}

/// One line per tolerance exceeded.
fn failures(
    options: &DiffOptions,
    channels: &[ChannelDiff],
    overall: &ErrorMetrics,
    flip: Option<&FlipDiff>,
) -> Vec<String> {
    let mut failures = Vec::new();
    if let Some(t) = options.max_abs {
        // The overall maximum is the largest channel maximum, so naming
        // each channel over the limit also covers the overall check.
        for c in channels {
            if !(c.metrics.max_abs <= t) {
                failures.push(format!(
                    "max abs error {} > {} (channel {}{})",
                    short(c.metrics.max_abs),
                    short(t),
                    pair_name(c),
                    non_finite_note(&c.metrics)
                ));
            }
        }
    }
    if let Some(t) = options.rmse {
        if !(overall.rmse <= t) {
            let what = if channels.len() == 1 {
                format!("channel {}", pair_name(&channels[0]))
            } else {
                "all channels".to_string()
            };
            failures.push(format!(
                "rmse {} > {} ({what}{})",
                short(overall.rmse),
                short(t),
                non_finite_note(overall)
            ));
        }
    }
    if let (Some(t), Some(f)) = (options.flip_threshold, &flip) {
        if f.non_finite > 0 {
            failures.push(format!(
                "FLIP cannot pass --flip-threshold {}: {} non-finite R, G, B values",
                short(t),
                f.non_finite
            ));
        } else if !(f.metrics.mean <= t) {
            failures.push(format!(
                "FLIP mean {} > {} (--flip-threshold; over {} pixels{})",
                short(f.metrics.mean),
                short(t),
                f.metrics.count,
                if f.masked { " under the mask" } else { "" }
            ));
        }
    }
    failures
}

/// An image's colours for FLIP: its `R, G, B` channels (linear; a PNG's
/// are decoded from sRGB, so re-encoding gives its codes back), with the
/// count of non-finite values among them.
fn colours(path: &Path, image: &LoadedImage) -> Result<(Vec<Vec3>, u64)> {
    let (Some(r), Some(g), Some(b)) = (image.channel("R"), image.channel("G"), image.channel("B"))
    else {
        return Err(Error::param(
            "--flip",
            format!(
                "{} has no R, G, B channels (it has {}); FLIP compares colour images",
                path.display(),
                channel_list(image)
            ),
        ));
    };
    let bad = [r, g, b]
        .iter()
        .map(|c| c.iter().filter(|v| !v.is_finite()).count() as u64)
        .sum();
    let colours = (r.iter().zip(g).zip(b))
        .map(|((r, g), b)| Vec3::new(*r, *g, *b))
        .collect();
    Ok((colours, bad))
}

/// The `(A name, B name)` pairs to compare, every name checked present.
fn channel_pairs(
    a: &Path,
    image_a: &LoadedImage,
    b: &Path,
    image_b: &LoadedImage,
    options: &DiffOptions,
) -> Result<Vec<(String, String)>> {
    let (names_a, names_b) = match (options.channels_a.is_empty(), options.channels_b.is_empty()) {
        (true, true) => {
            let common: Vec<String> = image_a
                .channels
                .iter()
                .map(|(n, _)| n.clone())
                .filter(|n| image_b.channel(n).is_some())
                .collect();
            if common.is_empty() {
                return Err(Error::param(
                    "--channels-a",
                    format!(
                        "{} ({}) and {} ({}) have no channel in common; name the channels \
                         to compare with --channels-a and --channels-b",
                        a.display(),
                        channel_list(image_a),
                        b.display(),
                        channel_list(image_b)
                    ),
                ));
            }
            (common.clone(), common)
        }
        (false, true) => (options.channels_a.clone(), options.channels_a.clone()),
        (true, false) => (options.channels_b.clone(), options.channels_b.clone()),
        (false, false) => {
            if options.channels_a.len() != options.channels_b.len() {
                return Err(Error::param(
                    "--channels-b",
                    format!(
                        "names {} channels but --channels-a names {}; they pair up by position",
                        options.channels_b.len(),
                        options.channels_a.len()
                    ),
                ));
            }
            (options.channels_a.clone(), options.channels_b.clone())
        }
    };
    // A list given for one side only is looked up on both; blame the option
    // the user actually wrote.
    let (option_a, option_b) = match (options.channels_a.is_empty(), options.channels_b.is_empty())
    {
        (false, true) => ("--channels-a", "--channels-a"),
        (true, false) => ("--channels-b", "--channels-b"),
        _ => ("--channels-a", "--channels-b"),
    };
    for (names, image, path, option) in [
        (&names_a, image_a, a, option_a),
        (&names_b, image_b, b, option_b),
    ] {
        if let Some(missing) = names.iter().find(|n| image.channel(n).is_none()) {
            return Err(Error::param(
                option,
                format!(
                    "{} has no channel {missing}; it has {}",
                    path.display(),
                    channel_list(image)
                ),
            ));
        }
    }
    Ok(names_a.into_iter().zip(names_b).collect())
}

/// `R, G, B, depth.Z`, or `no channels`.
fn channel_list(image: &LoadedImage) -> String {
    if image.channels.is_empty() {
        return "no channels".into();
    }
    image
        .channels
        .iter()
        .map(|(n, _)| n.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The mask's chosen channel, checked to match the images' size.
fn load_mask(path: &Path, channel: Option<&str>, images: &LoadedImage) -> Result<Vec<f32>> {
    let mask = read_image(path)?;
    if (mask.width, mask.height) != (images.width, images.height) {
        return Err(Error::file(
            path,
            None,
            format!(
                "the mask is {}×{} but the images are {}×{}",
                mask.width, mask.height, images.width, images.height
            ),
        ));
    }
    let chosen = match channel {
        Some(name) => mask.channel(name).ok_or_else(|| {
            Error::param(
                "--mask-channel",
                format!(
                    "{} has no channel {name}; it has {}",
                    path.display(),
                    channel_list(&mask)
                ),
            )
        })?,
        None => ["mask.Y", "Y", "R"]
            .iter()
            .find_map(|n| mask.channel(n))
            .or_else(|| mask.channels.first().map(|(_, v)| v.as_slice()))
            .ok_or_else(|| Error::file(path, None, "the mask image has no channels"))?,
    };
    Ok(chosen.to_vec())
}
