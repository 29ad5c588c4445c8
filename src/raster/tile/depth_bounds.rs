//! Per-tile depth bounds: the smallest and largest stored depth of the
//! 8×8 blocks of a tile as a two-dimensional sparse table, and what they
//! say about a rectangle of a triangle in a pass that reads depth without
//! writing it (counting passes, wedge passes): every pixel passes, every
//! pixel fails, or test.

use super::job::BLOCK;
use crate::raster::framebuffer::TILE_SIZE;
use crate::raster::setup::Plane;
use crate::raster::simd::LANES;
use crate::simd::f32x8;

/// What depth bounds say about a rectangle of a counting pass.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Verdict {
    /// No covered pixel in it counts.
    Skip,
    /// Every covered pixel in it counts: no depth test needed.
    CountAll,
    /// Test pixel by pixel.
    Test,
}

/// Blocks per tile side.
const BLOCKS: usize = TILE_SIZE / BLOCK as usize;

/// Smallest and largest stored depth over rectangles of 8×8 blocks of a
/// tile, as a two-dimensional sparse table: level `(kx, ky)` holds, for
/// every block `(bx, by)`, the bounds over the `2^kx × 2^ky` blocks from
/// it. Any rectangle of blocks is the union of four such (overlapping)
/// squares, so its bounds take four lookups.
pub(super) struct DepthBounds {
    /// `[ky * 4 + kx][by * 8 + bx]`.
    min: [[f32; BLOCKS * BLOCKS]; 16],
    max: [[f32; BLOCKS * BLOCKS]; 16],
}

impl DepthBounds {
    pub(super) fn of(depth: &[f32]) -> Self {
        let mut b = DepthBounds {
            min: [[0.0; BLOCKS * BLOCKS]; 16],
            max: [[0.0; BLOCKS * BLOCKS]; 16],
        };
        for k in 0..BLOCKS * BLOCKS {
            let (bx, by) = (k % BLOCKS, k / BLOCKS);
            let mut mn = f32x8::splat(f32::INFINITY);
            let mut mx = f32x8::splat(f32::NEG_INFINITY);
            for r in 0..LANES {
                let i = (by * LANES + r) * TILE_SIZE + bx * LANES;
                let v = f32x8::load(&depth[i..]);
                mn = mn.min(v);
                mx = mx.max(v);
            }
            b.min[0][k] = mn.to_array().into_iter().fold(f32::INFINITY, f32::min);
            b.max[0][k] = mx.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
        }
        let min = |a: f32, b: f32| if a < b { a } else { b };
        let max = |a: f32, b: f32| if a > b { a } else { b };
        for ky in 0..4 {
            for kx in 0..4 {
                if kx == 0 && ky == 0 {
                    continue;
                }
                // From the level one step smaller along x (or y).
                let (from, step) = if kx > 0 {
                    (ky * 4 + kx - 1, 1 << (kx - 1))
                } else {
                    ((ky - 1) * 4, BLOCKS << (ky - 1))
                };
                let (w, h) = (BLOCKS + 1 - (1 << kx), BLOCKS + 1 - (1 << ky));
                for by in 0..h {
                    for bx in 0..w {
                        let k = by * BLOCKS + bx;
                        b.min[ky * 4 + kx][k] = min(b.min[from][k], b.min[from][k + step]);
                        b.max[ky * 4 + kx][k] = max(b.max[from][k], b.max[from][k + step]);
                    }
                }
            }
        }
        b
    }

    /// The verdict for tile-local pixels `[x0, y0, x1, y1]` (inclusive)
    /// of a triangle with depth `plane` (screen origin of the tile
    /// `origin`), the test being `Greater` and the counted pixels the
    /// failing ones when `on_fail`.
    #[inline]
    pub(super) fn verdict(
        &self,
        plane: &Plane,
        plane2: Option<&Plane>,
        origin: (i32, i32),
        rect: [i32; 4],
        on_fail: bool,
    ) -> Verdict {
        let (lo, hi) = self.range(rect);
        let (all_fail, all_pass) = judge(plane, plane2, origin, rect, lo, hi);
        let (skip, count) = if on_fail {
            (all_pass, all_fail)
        } else {
            (all_fail, all_pass)
        };
        if skip {
            Verdict::Skip
        } else if count {
            Verdict::CountAll
        } else {
            Verdict::Test
        }
    }

    /// For a shift-counting pass, whether any fragment's test can differ
    /// between the stored depth `d` and `d × scale` over `rect` (`Skip`
    /// when the rectangle passes, or fails, at both throughout; never
    /// `CountAll`).
    #[inline]
    pub(super) fn verdict_scaled(
        &self,
        plane: &Plane,
        plane2: Option<&Plane>,
        origin: (i32, i32),
        rect: [i32; 4],
        scale: f32,
    ) -> Verdict {
        let (lo, hi) = self.range(rect);
        // The shifted depths lie between the products of the bounds (a
        // monotone f32 product, rounded the same way per pixel).
        let (lo, hi) = (lo.min(lo * scale), hi.max(hi * scale));
        let (all_fail, all_pass) = judge(plane, plane2, origin, rect, lo, hi);
        if all_fail || all_pass {
            Verdict::Skip
        } else {
            Verdict::Test
        }
    }

    /// Smallest and largest stored depth over the blocks of `rect`.
    fn range(&self, rect: [i32; 4]) -> (f32, f32) {
        let [bx0, by0, bx1, by1] = rect.map(|v| (v / BLOCK) as usize);
        // Largest powers of two within the extents: four squares.
        let kx = (usize::BITS - 1 - (bx1 - bx0 + 1).leading_zeros()) as usize;
        let ky = (usize::BITS - 1 - (by1 - by0 + 1).leading_zeros()) as usize;
        let level = ky * 4 + kx;
        let (bx2, by2) = (bx1 + 1 - (1 << kx), by1 + 1 - (1 << ky));
        let corners = [
            by0 * BLOCKS + bx0,
            by0 * BLOCKS + bx2,
            by2 * BLOCKS + bx0,
            by2 * BLOCKS + bx2,
        ];
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in corners {
            if self.min[level][k] < lo {
                lo = self.min[level][k];
            }
            if self.max[level][k] > hi {
                hi = self.max[level][k];
            }
        }
        (lo, hi)
    }
}

/// Whether every pixel of tile-local `rect` fails, and whether every one
/// passes, the `Greater` test of a triangle with depth `plane` (and
/// `plane2`, a merged quad's second) against stored depths within
/// `[lo, hi]`. Every pixel fails when even the nearest fragment is not in
/// front of the farthest stored depth; every one passes when the
/// farthest fragment is in front of the nearest stored depth. A quad's
/// pixels take one of its two planes: both must agree.
#[inline]
fn judge(
    plane: &Plane,
    plane2: Option<&Plane>,
    origin: (i32, i32),
    rect: [i32; 4],
    lo: f32,
    hi: f32,
) -> (bool, bool) {
    let screen = [
        rect[0] + origin.0,
        rect[1] + origin.1,
        rect[2] + origin.0,
        rect[3] + origin.1,
    ];
    let all_fail = plane_bound(plane, screen, true) <= lo
        && plane2.is_none_or(|p| plane_bound(p, screen, true) <= lo);
    let all_pass = plane_bound(plane, screen, false) > hi
        && plane2.is_none_or(|p| plane_bound(p, screen, false) > hi);
    (all_fail, all_pass)
}

/// Largest (`max`) or smallest depth the rasterizer gives any pixel of
/// `[x0, y0, x1, y1]` (screen, inclusive). The SIMD path computes a
/// pixel's depth as `clamp(row_base(y) + dx · cx(x))` with `row_base` and
/// `cx` rounded functions that are monotonic in `y` and `x`, and every
/// rounding is monotonic: the computed depth is monotonic in `x` and in
/// `y` separately, so its extremes over a rectangle are at the corners
/// the slopes' signs pick, evaluated here by the very same operations.
#[inline]
fn plane_bound(plane: &Plane, rect: [i32; 4], max: bool) -> f32 {
    let x = if (plane.dx >= 0.0) == max {
        rect[2]
    } else {
        rect[0]
    };
    let y = if (plane.dy >= 0.0) == max {
        rect[3]
    } else {
        rect[1]
    };
    // As the SIMD path's `max` / `min` (the same compare and pick).
    let v = plane.at(x, y);
    let v = if v > 0.0 { v } else { 0.0 };
    if v < 1.0 {
        v
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::tile::job::Lcg;

    /// The sparse table's bounds over any rectangle of blocks are the
    /// bounds of the pixels in those blocks, and verdicts follow them.
    #[test]
    fn depth_bounds_over_any_block_rectangle() {
        let mut rng = Lcg(9);
        let depth: Vec<f32> = (0..TILE_SIZE * TILE_SIZE + LANES)
            .map(|_| rng.below(1_000_000) as f32 * 1e-6)
            .collect();
        let b = DepthBounds::of(&depth);
        for by0 in 0..BLOCKS {
            for by1 in by0..BLOCKS {
                for bx0 in 0..BLOCKS {
                    for bx1 in bx0..BLOCKS {
                        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                        for y in by0 * 8..by1 * 8 + 8 {
                            for x in bx0 * 8..bx1 * 8 + 8 {
                                lo = lo.min(depth[y * TILE_SIZE + x]);
                                hi = hi.max(depth[y * TILE_SIZE + x]);
                            }
                        }
                        // Pixel rectangles inside those blocks.
                        let rect = [
                            (bx0 * 8 + rng.below(8) as usize) as i32,
                            (by0 * 8 + rng.below(8) as usize) as i32,
                            (bx1 * 8 + rng.below(8) as usize) as i32,
                            (by1 * 8 + rng.below(8) as usize) as i32,
                        ];
                        // A flat plane at depth d: all pass iff d > hi,
                        // all fail iff d <= lo.
                        for d in [lo, hi, (lo + hi) / 2.0, lo - 1e-3, hi + 1e-3] {
                            let plane = Plane {
                                v0: d,
                                ..Plane::default()
                            };
                            let want = if d > hi {
                                Verdict::Skip
                            } else if d <= lo {
                                Verdict::CountAll
                            } else {
                                Verdict::Test
                            };
                            assert!(want == b.verdict(&plane, None, (0, 0), rect, true));
                        }
                    }
                }
            }
        }
    }

    /// The depth the SIMD path gives a pixel is monotonic along x and y,
    /// so [`plane_bound`] over a rectangle bounds every pixel in it.
    #[test]
    fn plane_bounds_hold_every_pixel() {
        let mut rng = Lcg(5);
        for _ in 0..2000 {
            let f = |rng: &mut Lcg| (rng.below(2001) - 1000) as f32 * 1e-3;
            let plane = Plane {
                x0: f(&mut rng) * 500.0,
                y0: f(&mut rng) * 500.0,
                v0: f(&mut rng) + 0.5,
                dx: f(&mut rng) * 1e-3,
                dy: f(&mut rng) * 1e-3,
            };
            let x0 = rng.below(1000) as i32;
            let y0 = rng.below(1000) as i32;
            let rect = [x0, y0, x0 + rng.below(64) as i32, y0 + rng.below(8) as i32];
            let (lo, hi) = (
                plane_bound(&plane, rect, false),
                plane_bound(&plane, rect, true),
            );
            for y in rect[1]..=rect[3] {
                for x in (rect[0]..=rect[2]).step_by(LANES) {
                    let v = plane
                        .lanes(x, y)
                        .max(f32x8::splat(0.0))
                        .min(f32x8::splat(1.0))
                        .to_array();
                    for (k, v) in v.iter().enumerate() {
                        if x + (k as i32) <= rect[2] {
                            assert!(
                                lo <= *v && *v <= hi,
                                "{plane:?} {rect:?}: {v} outside {lo}..{hi}"
                            );
                        }
                    }
                }
            }
        }
    }
}
