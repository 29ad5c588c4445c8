//! The shadow-map techniques' shared options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

use crate::error::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// Largest map side `--map-size` accepts (the light view's own limit).
pub const MAX_MAP_SIZE: u32 = 16384;

/// The percentage-closer filter of a map look-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pcf {
    /// One tap: the texel holding the receiver's projection.
    #[default]
    Nearest,
    /// The four nearest texels, weighted bilinearly.
    Bilinear2x2,
    /// A 3×3 box of texels around the nearest.
    Box3x3,
    /// `n` taps of a Poisson disk (radius 1.5 texels), rotated per pixel.
    Poisson(u32),
}

impl FromStr for Pcf {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Pcf, String> {
        match s.trim() {
            "1" | "none" => Ok(Pcf::Nearest),
            "2x2" => Ok(Pcf::Bilinear2x2),
            "3x3" => Ok(Pcf::Box3x3),
            other => {
                let n = other
                    .strip_prefix("poisson:")
                    .and_then(|n| n.parse::<u32>().ok())
                    .ok_or_else(|| {
                        format!("unknown filter `{other}` (known: 1, 2x2, 3x3, poisson:N)")
                    })?;
                if n == 0 || n > 256 {
                    return Err(format!("poisson:{n}: N must be in 1..=256"));
                }
                Ok(Pcf::Poisson(n))
            }
        }
    }
}

impl fmt::Display for Pcf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pcf::Nearest => f.write_str("1"),
            Pcf::Bilinear2x2 => f.write_str("2x2"),
            Pcf::Box3x3 => f.write_str("3x3"),
            Pcf::Poisson(n) => write!(f, "poisson:{n}"),
        }
    }
}

/// The three depth biases, as the options give them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthBias {
    /// Constant bias, a fraction of the receiver's depth.
    pub constant: f64,
    /// Slope-scaled bias, in texels.
    pub slope: f64,
    /// Normal offset, in texels.
    pub normal_offset: f64,
}

impl DepthBias {
    /// Refuses negative or absurd values, naming the parameter.
    pub fn validate(&self) -> Result<()> {
        for (name, v, max) in [
            ("--depth-bias", self.constant, 1.0),
            ("--slope-bias", self.slope, 1e3),
            ("--normal-offset", self.normal_offset, 1e3),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(Error::param(name, format!("{v} is outside 0..={max}")));
            }
        }
        Ok(())
    }
}

/// Shadow maps' command-line options.
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct ShadowMapOptions {
    /// Shadow maps: texels per side of each light's depth map.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=MAX_MAP_SIZE as i64))]
    pub map_size: u32,
    /// Shadow maps: percentage-closer filter, 1 | 2x2 | 3x3 | poisson:N.
    #[arg(long, default_value = "1")]
    pub pcf: Pcf,
    /// Shadow maps: constant depth bias, a fraction of the receiver's depth
    /// (defaults of the three biases: the bias study in
    /// docs/algorithms/shadow-maps.md).
    #[arg(long, default_value_t = 1e-4)]
    pub depth_bias: f64,
    /// Shadow maps: slope-scaled depth bias, in texels.
    #[arg(long, default_value_t = 0.0)]
    pub slope_bias: f64,
    /// Shadow maps: normal offset of the receiver, in texels.
    #[arg(long, default_value_t = 0.5)]
    pub normal_offset: f64,
}

impl Default for ShadowMapOptions {
    /// The command line's defaults, written out (`shadow::options` tests
    /// that clap gives the same).
    fn default() -> Self {
        ShadowMapOptions {
            map_size: 1024,
            pcf: Pcf::Nearest,
            depth_bias: 1e-4,
            slope_bias: 0.0,
            normal_offset: 0.5,
        }
    }
}

impl ShadowMapOptions {
    /// The depth biases these options ask for.
    pub fn bias(&self) -> DepthBias {
        DepthBias {
            constant: self.depth_bias,
            slope: self.slope_bias,
            normal_offset: self.normal_offset,
        }
    }
}
