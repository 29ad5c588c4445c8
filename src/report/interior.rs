//! The interior of a frame: the foreground pixels away from geometric
//! edges, where an image error is the shading's and not a silhouette's
//! (where FLIP's edge detector and any one-pixel misalignment dominate).
//!
//! An *edge pixel* is a background pixel, a pixel at a depth
//! discontinuity, or a pixel at a normal discontinuity; a pixel is
//! *interior* when it is foreground and every edge pixel is farther than
//! [`INTERIOR_MARGIN`] pixels from it (Chebyshev distance, so its
//! 5 × 5 neighbourhood has none; the frame's border is no edge). Along each
//! row and column, with `d` the view depth and `n` the normal:
//!
//! - a depth discontinuity between neighbours `p`, `q`:
//!   `|d(q) − d(p)| > 4 %` of the nearer depth (both marked), or at `p`
//!   between `p − 1` and `p + 1`: `|d(p−1) − 2 d(p) + d(p+1)| > 1 %` of
//!   `d(p)` (a crease where depth stays continuous);
//! - a normal discontinuity: neighbouring normals more than 20° apart
//!   (both marked).
//!
//! This is the mask of the outside peer measurement, so interior figures
//! compare with its. A plane seen in perspective has a depth second
//! difference of `2 (Δd/d)²` relative, so where the first-difference test
//! stays quiet (below 4 %) the second stays below 0.32 %: only creases and
//! steps fire.

/// An edge pixel closer than this (Chebyshev, in pixels) or at it keeps a
/// pixel out of the interior.
pub const INTERIOR_MARGIN: usize = 2;

/// Relative depth step between neighbours that is a discontinuity.
pub const DEPTH_STEP: f32 = 0.04;

/// Relative depth second difference that is a crease.
pub const DEPTH_CREASE: f32 = 0.01;

/// Angle between neighbouring normals (degrees) that is a discontinuity.
pub const NORMAL_ANGLE_DEGREES: f32 = 20.0;

/// The interior mask of a `width × height` frame from its G-buffer:
/// view `depth`, unit `normal`s (`[x, y, z]` per pixel) and `foreground`
/// (a surface is seen). Row-major, row 0 at the top; `None` when the
/// slices do not hold `width × height` values.
pub fn interior_mask(
    width: usize,
    height: usize,
    depth: &[f32],
    normal: &[[f32; 3]],
    foreground: &[bool],
) -> Option<Vec<bool>> {
    let n = width.checked_mul(height)?;
    if depth.len() != n || normal.len() != n || foreground.len() != n {
        return None;
    }
    let cos_limit = NORMAL_ANGLE_DEGREES.to_radians().cos();
    let mut edge: Vec<bool> = foreground.iter().map(|&f| !f).collect();
    let fg = |i: usize| foreground[i] && depth[i].is_finite();
    // Pairs of neighbours `(i, j)` along a row (step 1) and a column
    // (step width), and triples `(h, i, j)` for the second difference.
    let pair = |edge: &mut Vec<bool>, i: usize, j: usize| {
        if !fg(i) || !fg(j) {
            return;
        }
        let (a, b) = (depth[i], depth[j]);
        let step = (b - a).abs() > DEPTH_STEP * a.abs().min(b.abs());
        let (p, q) = (normal[i], normal[j]);
        let dot = p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let norm = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
            * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
        // A zero or non-finite normal cannot be judged: an edge.
        let bent = !(norm > 0.0) || !(dot >= cos_limit * norm);
        if step || bent {
            edge[i] = true;
            edge[j] = true;
        }
    };
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if x + 1 < width {
                pair(&mut edge, i, i + 1);
            }
            if y + 1 < height {
                pair(&mut edge, i, i + width);
            }
        }
    }
    let crease = |h: usize, i: usize, j: usize| {
        fg(h)
            && fg(i)
            && fg(j)
            && (depth[h] - 2.0 * depth[i] + depth[j]).abs() > DEPTH_CREASE * depth[i].abs()
    };
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let along_row = x >= 1 && x + 1 < width && crease(i - 1, i, i + 1);
            let along_column = y >= 1 && y + 1 < height && crease(i - width, i, i + width);
            if along_row || along_column {
                edge[i] = true;
            }
        }
    }
    // Interior: foreground with no edge pixel in the (2m + 1)² window,
    // clipped at the frame's border. Separable: a row pass then a column
    // pass of "an edge within m".
    let m = INTERIOR_MARGIN;
    let mut near_row = vec![false; n];
    for y in 0..height {
        for x in 0..width {
            let (lo, hi) = (x.saturating_sub(m), (x + m).min(width - 1));
            near_row[y * width + x] = (lo..=hi).any(|xx| edge[y * width + xx]);
        }
    }
    let mut interior = vec![false; n];
    for y in 0..height {
        for x in 0..width {
            let (lo, hi) = (y.saturating_sub(m), (y + m).min(height - 1));
            let i = y * width + x;
            interior[i] = foreground[i] && !(lo..=hi).any(|yy| near_row[yy * width + x]);
        }
    }
    Some(interior)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat plane facing the camera at depth 5: the whole frame.
    fn flat(w: usize, h: usize) -> (Vec<f32>, Vec<[f32; 3]>, Vec<bool>) {
        (
            vec![5.0; w * h],
            vec![[0.0, 0.0, 1.0]; w * h],
            vec![true; w * h],
        )
    }

    #[test]
    fn a_plane_filling_the_frame_is_all_interior() {
        let (d, n, f) = flat(9, 7);
        let m = interior_mask(9, 7, &d, &n, &f).unwrap();
        assert!(m.iter().all(|&b| b));
        assert!(interior_mask(9, 7, &d[1..], &n, &f).is_none());
    }

    #[test]
    fn background_depth_steps_and_creases_keep_their_surroundings_out() {
        let (w, h) = (15, 9);
        // One background pixel at (3, 4): a 5 × 5 hole around it.
        let (d, n, mut f) = flat(w, h);
        f[4 * w + 3] = false;
        let m = interior_mask(w, h, &d, &n, &f).unwrap();
        for y in 0..h {
            for x in 0..w {
                let near = x.abs_diff(3) <= 2 && y.abs_diff(4) <= 2;
                assert_eq!(m[y * w + x], !near, "({x}, {y})");
            }
        }
        // A depth step between columns 7 and 8 (5 → 5.5, 10 %).
        let (mut d, n, f) = flat(w, h);
        for y in 0..h {
            for x in 8..w {
                d[y * w + x] = 5.5;
            }
        }
        let m = interior_mask(w, h, &d, &n, &f).unwrap();
        for x in 0..w {
            assert_eq!(m[4 * w + x], !(5..=10).contains(&x), "column {x}");
        }
        // A 0.5 % step is no edge (a step of 1 % or more is, through the
        // second difference).
        let small: Vec<f32> = d.iter().map(|&v| if v > 5.0 { 5.025 } else { v }).collect();
        assert!(interior_mask(w, h, &small, &n, &f)
            .unwrap()
            .iter()
            .all(|&b| b));
        // A crease: depth rising by 0.1 per column from column 7 on (a
        // wall's foot): continuous, but its second difference is 2 %.
        let (mut d, n, f) = flat(w, h);
        for y in 0..h {
            for x in 7..w {
                d[y * w + x] = 5.0 + 0.1 * (x - 6) as f32;
            }
        }
        let m = interior_mask(w, h, &d, &n, &f).unwrap();
        assert!(!m[4 * w + 6] && !m[4 * w + 4] && !m[4 * w + 8]);
        assert!(m[4 * w + 3] && m[4 * w + 10]);
    }

    #[test]
    fn normals_apart_by_more_than_twenty_degrees_are_an_edge() {
        let (w, h) = (13, 7);
        let tilt = |deg: f32| {
            let r = deg.to_radians();
            [r.sin(), 0.0, r.cos()]
        };
        for (deg, is_edge) in [(15.0, false), (25.0, true)] {
            let (d, mut n, f) = flat(w, h);
            for y in 0..h {
                for x in 7..w {
                    n[y * w + x] = tilt(deg);
                }
            }
            let m = interior_mask(w, h, &d, &n, &f).unwrap();
            assert_eq!(!m[3 * w + 6], is_edge, "{deg}°");
            assert_eq!(!m[3 * w + 9], is_edge, "{deg}°");
            assert!(m[3 * w + 2] && m[3 * w + 12], "{deg}°");
        }
    }
}
