//! The gather filter of interleaved sampling (Forest 2008, §4.2.2, after
//! Segovia et al. 2006, "Non-interleaved deferred shading of interleaved
//! sample patterns"): with [`crate::sampling::SamplePattern::Interleaved`]
//! each pixel of an `n × n` tile used a different sample set; averaging
//! the tile's pixels merges the `n²` sets into one of `n² N` samples, and
//! the average is limited to pixels of the same surface ("filter according
//! to the normal and depth discontinuities") so shadows do not bleed across
//! silhouettes.
//!
//! Output pixel `(x, y)` is the mean of the pixels in its `n × n` window
//! that pass the guide test against the centre `(x, y)`:
//!
//! - the window spans columns `x − ⌊(n−1)/2⌋ ..= x + ⌈(n−1)/2⌉` (and the
//!   same rows), so it holds each residue `(x mod n, y mod n)` — each
//!   interleaved set — exactly once; near the image border it is moved
//!   inside the image (keeping its size, hence still every set once) when
//!   the image is at least `n` wide (high); otherwise it is the whole
//!   width (height);
//! - a neighbour is kept when its guide is `Some((depth, normal))` with
//!   `|depth − depth_c| ≤ depth_tolerance · |depth_c|` and
//!   `normal · normal_c ≥ cos(max_normal_angle)`; background pixels
//!   (`None`) are never kept;
//! - the centre is always kept (so the mean is never 0/0, and a background
//!   centre keeps its own value).
//!
//! Sums are taken in `f64` in a fixed order (rows, then columns), so the
//! result is deterministic and independent of the thread count. The guide
//! is evaluated once per pixel (one allocation for the whole image); rows
//! are filtered in parallel without further allocation.

use glam::Vec3;
use rayon::prelude::*;

/// Thresholds of the discontinuity test of [`gather_filter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatherParams {
    /// Relative view-depth tolerance: a neighbour is kept if
    /// `|depth − depth_c| ≤ depth_tolerance · |depth_c|`.
    pub depth_tolerance: f32,
    /// Largest angle (radians) between a neighbour's unit normal and the
    /// centre's.
    pub max_normal_angle: f32,
}

impl Default for GatherParams {
    /// 5 % relative depth, 25° between normals.
    fn default() -> GatherParams {
        GatherParams {
            depth_tolerance: 0.05,
            max_normal_angle: 25f32.to_radians(),
        }
    }
}

/// A pixel value [`gather_filter`] can average: summed in `f64`.
pub trait GatherValue: Copy + Send + Sync {
    /// Adds `self` to the accumulator (up to three channels).
    fn add_to(self, acc: &mut [f64; 3]);
    /// The mean `acc / count`, rounded to `Self`.
    fn mean(acc: [f64; 3], count: u32) -> Self;
}

impl GatherValue for f32 {
    #[inline]
    fn add_to(self, acc: &mut [f64; 3]) {
        acc[0] += f64::from(self);
    }

    #[inline]
    fn mean(acc: [f64; 3], count: u32) -> f32 {
        (acc[0] / f64::from(count)) as f32
    }
}

impl GatherValue for Vec3 {
    #[inline]
    fn add_to(self, acc: &mut [f64; 3]) {
        acc[0] += f64::from(self.x);
        acc[1] += f64::from(self.y);
        acc[2] += f64::from(self.z);
    }

    #[inline]
    fn mean(acc: [f64; 3], count: u32) -> Vec3 {
        let c = f64::from(count);
        Vec3::new(
            (acc[0] / c) as f32,
            (acc[1] / c) as f32,
            (acc[2] / c) as f32,
        )
    }
}

/// The first index and length of the `n`-wide window of pixel `x` in a row
/// of `len` pixels (see the module documentation).
#[inline]
fn window(x: usize, len: usize, n: usize) -> (usize, usize) {
    if len <= n {
        return (0, len);
    }
    let lo = (n - 1) / 2;
    (x.saturating_sub(lo).min(len - n), n)
}

/// The interleaved-sampling gather filter (module documentation): for each
/// pixel of the `width × height` image `values` (row-major), the mean of
/// the pixels of its `n × n` window whose `guide` (view depth and unit
/// normal, `None` for background; called once per pixel index) matches
/// the centre's within `params`. `n ≤ 1` returns a copy.
///
/// # Panics
///
/// If `values.len() != width × height`.
pub fn gather_filter<T, G>(
    values: &[T],
    width: u32,
    height: u32,
    n: u32,
    guide: &G,
    params: GatherParams,
) -> Vec<T>
where
    T: GatherValue,
    G: Fn(usize) -> Option<(f32, Vec3)> + Sync,
{
    let (w, h) = (width as usize, height as usize);
    assert_eq!(
        values.len(),
        w * h,
        "values must hold width × height pixels"
    );
    if n <= 1 || values.is_empty() {
        return values.to_vec();
    }
    let n = n as usize;
    let guides: Vec<Option<(f32, Vec3)>> = (0..w * h).into_par_iter().map(guide).collect();
    let cos_max = params.max_normal_angle.cos();
    let tol = params.depth_tolerance;
    let mut out = values.to_vec();
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (y0, wh) = window(y, h, n);
        for (x, o) in row.iter_mut().enumerate() {
            let centre = y * w + x;
            let Some((dc, nc)) = guides[centre] else {
                continue; // background: only the centre is kept
            };
            let (x0, ww) = window(x, w, n);
            let limit = tol * dc.abs();
            let mut acc = [0.0f64; 3];
            let mut count = 0u32;
            for yy in y0..y0 + wh {
                for xx in x0..x0 + ww {
                    let i = yy * w + xx;
                    let keep = i == centre
                        || guides[i].is_some_and(|(d, nn)| {
                            (d - dc).abs() <= limit && nn.dot(nc) >= cos_max
                        });
                    if keep {
                        values[i].add_to(&mut acc);
                        count += 1;
                    }
                }
            }
            *o = T::mean(acc, count);
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_cover_every_residue_once() {
        for n in 2..=16usize {
            for len in [1usize, n - 1, n, n + 1, 3 * n + 2] {
                for x in 0..len {
                    let (x0, l) = window(x, len, n);
                    assert!(x0 <= x && x < x0 + l && x0 + l <= len);
                    if len >= n {
                        let mut seen = vec![0; n];
                        for xx in x0..x0 + l {
                            seen[xx % n] += 1;
                        }
                        assert!(seen.iter().all(|&c| c == 1), "n {n} len {len} x {x}");
                        if x >= (n - 1) / 2 && x + n / 2 < len {
                            assert_eq!(x0, x - (n - 1) / 2, "aligned away from borders");
                        }
                    }
                }
            }
        }
    }
}
