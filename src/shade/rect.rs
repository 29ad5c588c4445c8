//! Rectangle (parallelogram) lights: the projected solid angle of a polygon
//! in closed form (Lambert's formula), clipped to the receiver's hemisphere,
//! summed over a grid of sub-rectangles so that textured radiance and the
//! specular lobe can vary across the light.
//!
//! See `docs/shading.md` for the formulas and their error.

use super::brdf::Lobe;
use crate::scene::{Texture, TextureData};
use glam::DVec3;

/// Most sub-rectangles along one axis of a light's grid. Bounds the stack
/// arrays below and the cost per receiver point: a 16×16 grid costs about
/// 550 edge terms (one `atan2` each).
pub(crate) const MAX_GRID: usize = 16;

const MAX_VERTS: usize = (MAX_GRID + 1) * (MAX_GRID + 1);
const MAX_EDGES: usize = MAX_GRID * (MAX_GRID + 1);

/// A rect light's placement in `f64`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RectGeom {
    pub center: DVec3,
    pub u: DVec3,
    pub v: DVec3,
    /// `normalize(cross(u, v))`: the emitting side.
    pub normal: DVec3,
    pub two_sided: bool,
}

impl RectGeom {
    /// The light's area `|A| = 4 |u × v|`.
    #[cfg(test)]
    pub fn area(&self) -> f64 {
        4.0 * self.u.cross(self.v).length()
    }
}

/// The light cut into `nx × ny` sub-rectangles, each with its mean emitted
/// radiance (`radiance × mean texel` over the cell).
///
/// Cell `(i, j)` covers texture coordinates `s ∈ [i/nx, (i+1)/nx]`,
/// `t ∈ [j/ny, (j+1)/ny]`, i.e. points `center + (2s−1) u + (1−2t) v`.
#[derive(Debug, Clone)]
pub(crate) struct Grid {
    pub nx: usize,
    pub ny: usize,
    /// Mean radiance per cell, row-major (`j * nx + i`).
    pub le: Vec<DVec3>,
}

impl Grid {
    /// A textured light: each cell's radiance is `radiance` times the exact
    /// mean of the nearest-texel (piecewise constant) texture over the
    /// cell. Texel overlaps are computed in integer units of
    /// `1 / (nx · W)` so that texel-aligned cells average exactly.
    pub fn textured(nx: usize, ny: usize, radiance: DVec3, tex: &Texture) -> Grid {
        let (w, h) = (tex.width as usize, tex.height as usize);
        let mut le = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            let (r0, r1) = texel_range(j, ny, h);
            for i in 0..nx {
                let (c0, c1) = texel_range(i, nx, w);
                let mut acc = DVec3::ZERO;
                for r in r0..r1 {
                    let wr = overlap(j, ny, r, h) as f64;
                    for c in c0..c1 {
                        let wc = overlap(i, nx, c, w) as f64;
                        acc += texel(tex, c, r) * (wr * wc);
                    }
                }
                // Σ wc = W and Σ wr = H over the cell (its length in units).
                le.push(radiance * (acc / (w * h) as f64));
            }
        }
        Grid { nx, ny, le }
    }
}

/// Grid sizes `(diffuse, specular)` for a light with this texture.
///
/// Diffuse: one cell per texel up to [`MAX_GRID`] per axis. Specular:
/// [`MAX_GRID`] cells, or for small textures the largest multiple of the
/// texel count not above it, so that cells stay texel-aligned and the
/// diffuse sum stays exact. (Untextured lights size their grid per
/// receiver point instead: [`super::brdf::lobe_cells`].)
pub(crate) fn grid_sizes(tex: &Texture) -> ((usize, usize), (usize, usize)) {
    let diffuse = |n: usize| n.clamp(1, MAX_GRID);
    let spec = |n: usize| {
        if n == 0 || n > MAX_GRID {
            MAX_GRID
        } else {
            n * (MAX_GRID / n)
        }
    };
    let (w, h) = (tex.width as usize, tex.height as usize);
    ((diffuse(w), diffuse(h)), (spec(w), spec(h)))
}

/// Texels `[first, last)` that cell `i` of `n` overlaps, for `size` texels.
fn texel_range(i: usize, n: usize, size: usize) -> (usize, usize) {
    let lo = i * size / n;
    let hi = ((i + 1) * size).div_ceil(n);
    (lo, hi.min(size))
}

/// Overlap of cell `i` of `n` with texel `c` of `size`, in units of
/// `1 / (n · size)` of the whole axis.
fn overlap(i: usize, n: usize, c: usize, size: usize) -> usize {
    let (a0, a1) = (i * size, (i + 1) * size);
    let (b0, b1) = (c * n, (c + 1) * n);
    a1.min(b1).saturating_sub(a0.max(b0))
}

/// The linear RGB value of texel `(column, row)`; scalar textures read as
/// grey, and a texel outside the data (never for a validated texture) as 1.
pub(crate) fn texel(tex: &Texture, column: usize, row: usize) -> DVec3 {
    let k = row * tex.width as usize + column;
    match &tex.data {
        TextureData::Rgb(d) => d.get(k).map_or(DVec3::ONE, |c| c.as_dvec3()),
        TextureData::Scalar(d) => d.get(k).map_or(DVec3::ONE, |&c| DVec3::splat(c.into())),
    }
}

/// `∫_light Le(x) f_r cos_p cos_x / r² dA` for receiver `p` with BRDF
/// `lobe`, the light's radiance given by `grid` (visibility 1).
///
/// Each cell's projected solid angle `Φ_j` (clipped to `n·w ≥ 0`) is exact
/// (Lambert's formula); the diffuse term is `albedo/π Σ_j Le_j Φ_j`. The
/// specular term (when `with_spec`) is `Σ_j Le_j Φ_j f̄_j` with `f̄_j` the
/// lobe's mean over cell `j`: for whole cells a density-weighted
/// centre-and-corners rule (O(h⁴) where lobe and density are smooth), for
/// cells the horizon cuts the lobe at the cell's `cos_p`-weighted
/// centroid.
pub(crate) fn integrate(
    geom: &RectGeom,
    (nx, ny): (usize, usize),
    le: impl Fn(usize) -> DVec3,
    lobe: &Lobe,
    p: DVec3,
    with_spec: bool,
) -> DVec3 {
    // One-sidedness: every point of a planar light sees p at the same side,
    // so cos_x = 0 everywhere when p is behind it (or in its plane).
    let side = geom.normal.dot(p - geom.center);
    if side.is_nan() || side == 0.0 || (side < 0.0 && !geom.two_sided) {
        return DVec3::ZERO;
    }
    // Orientation of Lambert's sum for this vertex order (+u first, then −v):
    // the cell's winding seen from p flips with the side p is on.
    let sigma = side.signum();

    let n = lobe.n;
    let base = geom.center - p;

    if nx <= 1 && ny <= 1 && !with_spec {
        // The common case (untextured, Lambertian): one polygon, no
        // grid arrays to fill.
        let sum = whole_light_sum(geom, base, n);
        return le(0) * (0.5 * (sigma * sum).max(0.0)) * lobe.diffuse;
    }

    let (nx, ny) = (nx.clamp(1, MAX_GRID), ny.clamp(1, MAX_GRID));
    let mut grid = GridView {
        nx,
        ny,
        stride: nx + 1,
        rel: [DVec3::ZERO; MAX_VERTS],
        height: [0.0f64; MAX_VERTS],
        horiz: [0.0f64; MAX_EDGES],
        vert: [0.0f64; MAX_EDGES],
    };
    grid.place_vertices(geom, base, n);
    grid.shared_edge_terms(n);

    // At every grid vertex: the lobe's shape, and the density of the
    // projected solid angle per unit light area, cos_p cos_x / r², for the
    // cell rule below.
    let mut lobe_at = [0.0f64; MAX_VERTS];
    let mut dens_at = [0.0f64; MAX_VERTS];
    if with_spec {
        for k in 0..(ny + 1) * grid.stride {
            let (lobe_k, dens_k) = lobe_and_density(grid.rel[k], lobe, geom.normal);
            lobe_at[k] = lobe_k;
            dens_at[k] = dens_k;
        }
    }

    let mut diffuse = DVec3::ZERO;
    let mut specular_rgb = DVec3::ZERO;
    for j in 0..ny {
        for i in 0..nx {
            let Some(cell) = grid.cell(i, j, n) else {
                continue;
            };
            // Lambert: projected solid angle = ½ |Σ β_i n·γ̂_i|. The sign is
            // known (sigma); a tiny negative is rounding, not light.
            let phi = 0.5 * (sigma * cell.sum).max(0.0);
            if phi == 0.0 {
                continue;
            }
            let cell_light = le(j * nx + i) * phi;
            diffuse += cell_light;
            if with_spec {
                let shape = if cell.clipped {
                    clipped_cell_shape(cell.centre, lobe)
                } else {
                    whole_cell_shape(&cell, lobe, geom.normal, (&lobe_at, &dens_at))
                };
                specular_rgb += cell_light * shape;
            }
        }
    }
    diffuse * lobe.diffuse + lobe.specular_scale() * specular_rgb
}

/// Lambert's sum over the whole light as one polygon (`base`: the light's
/// centre relative to the receiver), in a grid cell's vertex order.
#[inline]
fn whole_light_sum(geom: &RectGeom, base: DVec3, n: DVec3) -> f64 {
    let (u, v) = (geom.u, geom.v);
    let quad = [base - u + v, base + u + v, base + u - v, base - u - v];
    let heights = quad.map(|r| n.dot(r));
    if heights.iter().all(|&h| h >= 0.0) {
        (0..4)
            .map(|k| edge_term(quad[k], quad[(k + 1) % 4], n))
            .sum()
    } else if heights.iter().all(|&h| h <= 0.0) {
        0.0
    } else {
        clipped_sum(quad, heights, n).0
    }
}

/// The light's `nx × ny` grid seen from the receiver: its vertices and
/// the edge terms neighbouring cells share. Stack arrays sized for
/// [`MAX_GRID`].
struct GridView {
    nx: usize,
    ny: usize,
    /// Vertices per row (`nx + 1`).
    stride: usize,
    /// Vertex `j * stride + i` relative to the receiver.
    rel: [DVec3; MAX_VERTS],
    /// Its height above the receiver's horizon.
    height: [f64; MAX_VERTS],
    /// `horiz[j * nx + i]`: the edge term of (i, j) → (i+1, j).
    horiz: [f64; MAX_EDGES],
    /// `vert[j * stride + i]`: the edge term of (i, j) → (i, j+1).
    vert: [f64; MAX_EDGES],
}

/// One grid cell's part of Lambert's sum, clipped to the horizon.
struct CellSum {
    /// Lambert's sum over the (clipped) cell.
    sum: f64,
    /// Whole cell: the sum of its four corners (four times their mean);
    /// clipped: the clipped polygon's height-weighted centroid.
    centre: DVec3,
    /// Whether the horizon cuts the cell.
    clipped: bool,
    /// The corners' vertex indices, in Lambert's order.
    corners: [usize; 4],
}

impl GridView {
    /// Grid vertices relative to the receiver, and their heights above
    /// the horizon.
    #[inline]
    fn place_vertices(&mut self, geom: &RectGeom, base: DVec3, n: DVec3) {
        let (nx, ny, stride) = (self.nx, self.ny, self.stride);
        for j in 0..=ny {
            let tv = 1.0 - 2.0 * j as f64 / ny as f64;
            for i in 0..=nx {
                let su = 2.0 * i as f64 / nx as f64 - 1.0;
                let r = base + geom.u * su + geom.v * tv;
                self.rel[j * stride + i] = r;
                self.height[j * stride + i] = n.dot(r);
            }
        }
    }

    /// Edge terms shared by neighbouring cells, only where both ends are
    /// above the horizon (the only place [`GridView::cell`] reads them).
    #[inline]
    fn shared_edge_terms(&mut self, n: DVec3) {
        let (nx, ny, stride) = (self.nx, self.ny, self.stride);
        for j in 0..=ny {
            for i in 0..nx {
                let (a, b) = (j * stride + i, j * stride + i + 1);
                if self.height[a] >= 0.0 && self.height[b] >= 0.0 {
                    self.horiz[j * nx + i] = edge_term(self.rel[a], self.rel[b], n);
                }
            }
        }
        for j in 0..ny {
            for i in 0..=nx {
                let (a, b) = (j * stride + i, (j + 1) * stride + i);
                if self.height[a] >= 0.0 && self.height[b] >= 0.0 {
                    self.vert[j * stride + i] = edge_term(self.rel[a], self.rel[b], n);
                }
            }
        }
    }

    /// Cell `(i, j)`'s sum, `None` when it is wholly below the horizon.
    #[inline]
    fn cell(&self, i: usize, j: usize, n: DVec3) -> Option<CellSum> {
        let (nx, stride) = (self.nx, self.stride);
        let corners = [
            j * stride + i,
            j * stride + i + 1,
            (j + 1) * stride + i + 1,
            (j + 1) * stride + i,
        ];
        let heights = corners.map(|k| self.height[k]);
        let (sum, centre, clipped) = if heights.iter().all(|&h| h >= 0.0) {
            let sum = self.horiz[j * nx + i] + self.vert[j * stride + i + 1]
                - self.horiz[(j + 1) * nx + i]
                - self.vert[j * stride + i];
            (
                sum,
                corners.iter().map(|&k| self.rel[k]).sum::<DVec3>(),
                false,
            )
        } else if heights.iter().all(|&h| h <= 0.0) {
            return None;
        } else {
            let (sum, centroid) = clipped_sum(corners.map(|k| self.rel[k]), heights, n);
            (sum, centroid, true)
        };
        Some(CellSum {
            sum,
            centre,
            clipped,
            corners,
        })
    }
}

/// The lobe's shape for a cell the horizon cuts: corners below the horizon
/// are not part of the cell, so the lobe at the cell's cos_p-weighted
/// centroid.
#[inline]
fn clipped_cell_shape(centroid: DVec3, lobe: &Lobe) -> f64 {
    let len = centroid.length();
    if len > 0.0 {
        lobe.spec_shape(centroid / len)
    } else {
        0.0
    }
}

/// The lobe's mean over a whole cell under its own measure: nodes at the
/// centre (weight 2/3) and the corners (1/12 each), each weighted by the
/// density there. With a uniform density this is (2 · midpoint + corner
/// mean) / 3, which cancels the h² error terms the two rules have with
/// opposite signs. `(lobe_at, dens_at)`: lobe shape and density per grid
/// vertex.
#[inline]
fn whole_cell_shape(
    cell: &CellSum,
    lobe: &Lobe,
    light_normal: DVec3,
    (lobe_at, dens_at): (&[f64; MAX_VERTS], &[f64; MAX_VERTS]),
) -> f64 {
    let (lobe_m, dens_m) = lobe_and_density(cell.centre * 0.25, lobe, light_normal);
    let mut num = 8.0 * lobe_m * dens_m;
    let mut den = 8.0 * dens_m;
    for &k in &cell.corners {
        num += lobe_at[k] * dens_at[k];
        den += dens_at[k];
    }
    if den > 0.0 && den.is_finite() {
        num / den
    } else {
        lobe_m
    }
}

/// The lobe's shape toward `r` (a vector from the receiver to a point on
/// the light) and the density `cos_p |cos_x| / |r|²` of projected solid
/// angle per unit light area there (the light's side was checked before).
fn lobe_and_density(r: DVec3, lobe: &Lobe, light_normal: DVec3) -> (f64, f64) {
    let r2 = r.length_squared();
    if !(r2 > 0.0 && r2.is_finite()) {
        return (0.0, 0.0);
    }
    let len = r2.sqrt();
    let w = r / len;
    let dens = lobe.n.dot(w).max(0.0) * light_normal.dot(w).abs() / r2;
    (lobe.spec_shape(w), dens)
}

/// Lambert's sum over the quad `v` clipped to `n·x ≥ 0` (Sutherland–
/// Hodgman against one plane: at most 5 vertices), and the clipped
/// polygon's height-weighted centroid (see [`weighted_centroid`]).
fn clipped_sum(v: [DVec3; 4], h: [f64; 4], n: DVec3) -> (f64, DVec3) {
    let mut out = [DVec3::ZERO; 8];
    let mut m = 0;
    for k in 0..4 {
        let (a, ha) = (v[k], h[k]);
        let (b, hb) = (v[(k + 1) % 4], h[(k + 1) % 4]);
        if ha >= 0.0 {
            out[m] = a;
            m += 1;
        }
        if (ha >= 0.0) != (hb >= 0.0) {
            // ha − hb is non-zero: one is ≥ 0, the other < 0.
            let t = ha / (ha - hb);
            out[m] = a + (b - a) * t;
            m += 1;
        }
    }
    let mut sum = 0.0;
    for k in 0..m {
        sum += edge_term(out[k], out[(k + 1) % m], n);
    }
    (sum, weighted_centroid(&out[..m], n))
}

/// The centroid of a planar polygon (vectors from the receiver) under an
/// area density proportional to the height `n·x` above the horizon, which
/// is how `cos_p` weights a cell the horizon cuts: the light there sits
/// nearer the cell's high side than its vertex mean does. Exact per
/// triangle of a fan: `∫ x h dA = A/12 (Σ x_i h_i + Σ x_i Σ h_i)`,
/// `∫ h dA = A/3 Σ h_i`. Falls back to the vertex mean for degenerate
/// polygons.
fn weighted_centroid(poly: &[DVec3], n: DVec3) -> DVec3 {
    let mut moment = DVec3::ZERO;
    let mut mass = 0.0;
    for k in 1..poly.len().saturating_sub(1) {
        let (a, b, c) = (poly[0], poly[k], poly[k + 1]);
        let area = 0.5 * (b - a).cross(c - a).length();
        let (ha, hb, hc) = (n.dot(a).max(0.0), n.dot(b).max(0.0), n.dot(c).max(0.0));
        let hs = ha + hb + hc;
        moment += (a * ha + b * hb + c * hc + (a + b + c) * hs) * (area / 12.0);
        mass += area * hs / 3.0;
    }
    if mass > 0.0 && mass.is_finite() {
        moment / mass
    } else {
        poly.iter().sum::<DVec3>() / poly.len().max(1) as f64
    }
}

/// One term of Lambert's formula, `β · n·γ̂` for the edge `a → b` (vectors
/// from the receiver, any length): `β` is the angle the edge subtends and
/// `γ̂ = normalize(a × b)`. `atan2` keeps `β` accurate at every angle; an
/// edge through the receiver (`a × b = 0`) contributes nothing rather than
/// NaN, and the term is bounded by π in magnitude, so the sum stays finite.
fn edge_term(a: DVec3, b: DVec3, n: DVec3) -> f64 {
    let c = a.cross(b);
    let s = c.length();
    if s > 0.0 && s.is_finite() {
        let beta = s.atan2(a.dot(b));
        beta * (n.dot(c) / s).clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_ranges_cover_the_axis() {
        for size in 1..40 {
            for n in 1..=MAX_GRID {
                let mut total = 0;
                for i in 0..n {
                    let (lo, hi) = texel_range(i, n, size);
                    let w: usize = (lo..hi).map(|c| overlap(i, n, c, size)).sum();
                    assert_eq!(w, size, "cell {i}/{n} of {size}");
                    total += w;
                }
                assert_eq!(total, n * size);
            }
        }
    }

    #[test]
    fn projected_solid_angle_of_overhead_square() {
        // A square far overhead: projected solid angle ≈ area / d².
        let geom = RectGeom {
            center: DVec3::new(0.0, 0.0, 100.0),
            u: DVec3::X * 0.5,
            v: DVec3::Y * -0.5,
            normal: DVec3::Z * -1.0,
            two_sided: false,
        };
        let lobe = Lobe::new(&super::super::SurfacePoint {
            p: glam::Vec3::ZERO,
            n: glam::Vec3::Z,
            ng: glam::Vec3::Z,
            wo: glam::Vec3::Z,
            albedo: glam::Vec3::splat(std::f32::consts::PI),
            specular: glam::Vec3::ZERO,
            shininess: 0.0,
        });
        let e = integrate(&geom, (1, 1), |_| DVec3::ONE, &lobe, DVec3::ZERO, false);
        let expect = geom.area() / 1e4;
        assert!((e.x / expect - 1.0).abs() < 1e-4, "{e} vs {expect}");
    }
}
