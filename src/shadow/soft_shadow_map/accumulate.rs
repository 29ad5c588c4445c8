//! Summing the micro-patches' occlusion into the soft shadow map,
//! Larrabee-style: patches are binned to 64 × 64-texel tiles of the map
//! (a stable counting sort, so each tile's list is in patch order), then
//! each tile is accumulated by one worker, patch after patch, eight texels
//! at a time through the SIMD facade. No value depends on the thread count
//! or the SIMD level: one tile, one worker, one fixed order, and the lanes'
//! operations are the scalar ones ([`super::geometry::patch_occlusion`]).
//!
//! Memory: the receiver map and the SSM (one `f32` per texel each), the
//! patch list and the bins (per patch × tile, never per patch × texel),
//! and one tile buffer per worker (two in `f16-batched`: the batch and the
//! intermediate sum).

use super::geometry::{reach, MAX_G};
use super::Accumulate;
use crate::simd::f32x8;
use half::f16;
use rayon::prelude::*;

/// Side of an SSM tile, in texels (a multiple of 8).
pub const TILE: usize = 64;

/// Micro-patches of one pass, sorted by row then column of the soft
/// shadow map (the order they are summed in: "patch order").
#[derive(Debug, Clone, Default)]
pub struct Patches {
    /// Column of each patch's texel, in SSM texels.
    pub x: Vec<u32>,
    /// Row.
    pub y: Vec<u32>,
    /// Its depth `z_O` along the light's normal (linear, f32).
    pub depth: Vec<f32>,
    /// Per SSM row `r`, the patches of that row are
    /// `row_start[r]..row_start[r + 1]`.
    pub row_start: Vec<u32>,
    /// Smallest patch depth (`+∞` when empty), set by [`Patches::finish`].
    pub min_depth: f32,
}

impl Patches {
    /// Number of patches.
    pub fn len(&self) -> usize {
        self.depth.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.depth.is_empty()
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> u64 {
        (self.len() * 12 + self.row_start.len() * 4) as u64
    }

    /// Sets the derived fields once the patches are in.
    pub fn finish(&mut self) {
        self.min_depth = self.depth.iter().copied().fold(f32::INFINITY, f32::min);
    }

    /// The patches of SSM row `r` with columns in `lo..=hi`, as an index
    /// range (patch order).
    pub fn row_range(&self, r: usize, lo: i64, hi: i64) -> std::ops::Range<usize> {
        let (a, b) = (self.row_start[r] as usize, self.row_start[r + 1] as usize);
        let xs = &self.x[a..b];
        let s = xs.partition_point(|&x| (x as i64) < lo);
        let e = xs.partition_point(|&x| (x as i64) <= hi);
        a + s..a + e
    }
}

/// What the accumulation needs to know of the light and the map.
#[derive(Debug, Clone, Copy)]
pub struct Params {
    /// SSM width in texels.
    pub width: usize,
    /// SSM height in texels.
    pub height: usize,
    /// `Δx / 2hx`: a texel's tangent width over the light's width.
    pub ax: f32,
    /// `Δy / 2hy`.
    pub ay: f32,
    /// `hx / Δx`, for the reach in texels.
    pub hx_texels: f64,
    /// `hy / Δy`.
    pub hy_texels: f64,
    /// Relative depth bias: a patch occludes a receiver at `z_R` only when
    /// `z_O < z_R − z_R · bias`.
    pub bias: f32,
    /// Accumulation precision.
    pub accumulate: Accumulate,
}

/// Patches per batch in `f16-batched`: `M` patches in `⌊√M⌋` batches.
pub fn batch_size(m: usize) -> usize {
    let batches = ((m as f64).sqrt().floor() as usize).max(1);
    m.div_ceil(batches).max(1)
}

/// `a + x` in IEEE half precision, as fp16 blending does it: the fragment's
/// value is rounded to half, the sum of two halves (exact in f64) is
/// rounded to half once, to nearest even.
#[inline]
pub fn add_f16(a: f16, x: f32) -> f16 {
    f16::from_f64(a.to_f64() + f16::from_f32(x).to_f64())
}

/// The soft shadow map: summed occlusion per texel (for f16 modes the f16
/// values, exactly), merged over passes by max; 0 where there is no
/// receiver. `receivers` is the receiver depth per SSM texel (`+∞` none).
pub fn soft_shadow_map(params: &Params, receivers: &[f32], passes: &[&Patches]) -> Vec<f32> {
    let (w, h) = (params.width, params.height);
    debug_assert_eq!(receivers.len(), w * h);
    let (tx, ty) = (w.div_ceil(TILE), h.div_ceil(TILE));
    // Per tile: the receivers' depths, padded with +∞, and the deepest.
    let tile_zmax: Vec<f32> = (0..tx * ty)
        .into_par_iter()
        .map(|t| {
            let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
            let mut m = f32::NEG_INFINITY;
            for y in y0..(y0 + TILE).min(h) {
                for &z in &receivers[y * w + x0..y * w + (x0 + TILE).min(w)] {
                    if z.is_finite() && z > m {
                        m = z;
                    }
                }
            }
            m
        })
        .collect();
    let zmax = tile_zmax.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let bins: Vec<Bins> = passes
        .iter()
        .map(|p| Bins::new(params, p, &tile_zmax, zmax, tx, ty))
        .collect();
    let tiles: Vec<Vec<f32>> = (0..tx * ty)
        .into_par_iter()
        .map(|t| {
            let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
            let mut recv = vec![f32::INFINITY; TILE * TILE];
            for y in y0..(y0 + TILE).min(h) {
                let cols = TILE.min(w - x0);
                recv[(y - y0) * TILE..(y - y0) * TILE + cols]
                    .copy_from_slice(&receivers[y * w + x0..y * w + x0 + cols]);
            }
            let tile = TileJob {
                params,
                x0,
                y0,
                zmax: tile_zmax[t],
                recv: &recv,
            };
            let mut out = vec![0.0f32; TILE * TILE];
            for (pass, bins) in passes.iter().zip(&bins) {
                let list = bins.list(t);
                if list.is_empty() {
                    continue;
                }
                let acc = tile.run(pass, list);
                for (o, a) in out.iter_mut().zip(&acc) {
                    // Two passes merge by max (§3.5); one pass is its sum.
                    if *a > *o {
                        *o = *a;
                    }
                }
            }
            out
        })
        .collect();
    let mut ssm = vec![0.0f32; w * h];
    for (t, tile) in tiles.iter().enumerate() {
        let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
        for y in y0..(y0 + TILE).min(h) {
            let cols = TILE.min(w - x0);
            ssm[y * w + x0..y * w + x0 + cols]
                .copy_from_slice(&tile[(y - y0) * TILE..(y - y0) * TILE + cols]);
        }
    }
    ssm
}

/// Patch indices per tile, in patch order (CSR).
struct Bins {
    start: Vec<u32>,
    patches: Vec<u32>,
}

impl Bins {
    fn new(
        params: &Params,
        p: &Patches,
        tile_zmax: &[f32],
        zmax: f32,
        tx: usize,
        ty: usize,
    ) -> Bins {
        const CHUNK: usize = 4096;
        // Per chunk of patches, its (tile, patch) pairs in patch order;
        // concatenated in chunk order and counting-sorted by tile (stable),
        // so each tile's list is in patch order whatever the scheduling.
        let pairs: Vec<Vec<(u32, u32)>> = (0..p.len().div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let mut out = Vec::new();
                for i in c * CHUNK..((c + 1) * CHUNK).min(p.len()) {
                    let z = p.depth[i];
                    if !occludes(z, zmax, params.bias) {
                        continue;
                    }
                    let (x, y) = (p.x[i] as i64, p.y[i] as i64);
                    let rx = reach(params.hx_texels, 1.0, z as f64, zmax as f64);
                    let ry = reach(params.hy_texels, 1.0, z as f64, zmax as f64);
                    let t = TILE as i64;
                    let tx0 = ((x - rx).max(0) / t) as usize;
                    let tx1 = (((x + rx) / t) as usize).min(tx - 1);
                    let ty0 = ((y - ry).max(0) / t) as usize;
                    let ty1 = (((y + ry) / t) as usize).min(ty - 1);
                    for j in ty0..=ty1 {
                        for k in tx0..=tx1 {
                            let zt = tile_zmax[j * tx + k];
                            if !occludes(z, zt, params.bias) {
                                continue;
                            }
                            // The reach with this tile's deepest receiver.
                            let rx = reach(params.hx_texels, 1.0, z as f64, zt as f64);
                            let ry = reach(params.hy_texels, 1.0, z as f64, zt as f64);
                            let (kx0, ky0) = ((k * TILE) as i64, (j * TILE) as i64);
                            if x + rx >= kx0
                                && x - rx < kx0 + t
                                && y + ry >= ky0
                                && y - ry < ky0 + t
                            {
                                out.push(((j * tx + k) as u32, i as u32));
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut start = vec![0u32; tx * ty + 1];
        for &(t, _) in pairs.iter().flatten() {
            start[t as usize + 1] += 1;
        }
        for i in 0..tx * ty {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut patches = vec![0u32; start[tx * ty] as usize];
        for &(t, i) in pairs.iter().flatten() {
            patches[fill[t as usize] as usize] = i;
            fill[t as usize] += 1;
        }
        Bins { start, patches }
    }

    fn list(&self, t: usize) -> &[u32] {
        &self.patches[self.start[t] as usize..self.start[t + 1] as usize]
    }
}

/// Whether a patch at `z_o` can occlude a receiver at `z_r`.
#[inline]
pub fn occludes(z_o: f32, z_r: f32, bias: f32) -> bool {
    z_o < z_r - z_r * bias
}

struct TileJob<'a> {
    params: &'a Params,
    x0: usize,
    y0: usize,
    zmax: f32,
    recv: &'a [f32],
}

impl TileJob<'_> {
    /// One pass's summed occlusion over this tile.
    fn run(&self, p: &Patches, list: &[u32]) -> Vec<f32> {
        let n = TILE * TILE;
        match self.params.accumulate {
            Accumulate::F32 => {
                let mut acc = vec![0.0f32; n];
                for &i in list {
                    self.patch(p, i as usize, |k, occ| {
                        let a = f32x8::load(&acc[k..k + 8]) + occ;
                        acc[k..k + 8].copy_from_slice(&a.to_array());
                    });
                }
                acc
            }
            Accumulate::F16 => {
                let mut acc = vec![f16::ZERO; n];
                for &i in list {
                    self.patch(p, i as usize, |k, occ| blend_f16(&mut acc[k..k + 8], occ));
                }
                acc.iter().map(|v| v.to_f32()).collect()
            }
            Accumulate::F16Batched => {
                let size = batch_size(p.len());
                let mut batch = vec![f16::ZERO; n];
                let mut total = vec![f16::ZERO; n];
                let mut current = usize::MAX;
                let flush = |batch: &mut [f16], total: &mut [f16]| {
                    for (t, b) in total.iter_mut().zip(batch.iter_mut()) {
                        *t = add_f16(*t, b.to_f32());
                        *b = f16::ZERO;
                    }
                };
                for &i in list {
                    let b = i as usize / size;
                    if b != current {
                        if current != usize::MAX {
                            flush(&mut batch, &mut total);
                        }
                        current = b;
                    }
                    self.patch(p, i as usize, |k, occ| blend_f16(&mut batch[k..k + 8], occ));
                }
                flush(&mut batch, &mut total);
                total.iter().map(|v| v.to_f32()).collect()
            }
        }
    }

    /// Calls `add(tile offset, occlusion of 8 texels)` for every 8-texel
    /// run of this tile inside patch `i`'s penumbra extent.
    #[inline]
    fn patch(&self, p: &Patches, i: usize, mut add: impl FnMut(usize, f32x8)) {
        let prm = self.params;
        let z_o = p.depth[i];
        if !occludes(z_o, self.zmax, prm.bias) {
            return;
        }
        let (px, py) = (p.x[i] as i64, p.y[i] as i64);
        let rx = reach(prm.hx_texels, 1.0, z_o as f64, self.zmax as f64);
        let ry = reach(prm.hy_texels, 1.0, z_o as f64, self.zmax as f64);
        let (x0, y0) = (self.x0 as i64, self.y0 as i64);
        let t = TILE as i64;
        let (xa, xb) = ((px - rx).max(x0) - x0, (px + rx).min(x0 + t - 1) - x0);
        let (ya, yb) = ((py - ry).max(y0) - y0, (py + ry).min(y0 + t - 1) - y0);
        if xa > xb || ya > yb {
            return;
        }
        let zo = f32x8::splat(z_o);
        let bias = f32x8::splat(prm.bias);
        let (ax, ay) = (f32x8::splat(prm.ax), f32x8::splat(prm.ay));
        let (half, one, zero, cap) = (
            f32x8::splat(0.5),
            f32x8::splat(1.0),
            f32x8::ZERO,
            f32x8::splat(MAX_G),
        );
        let sat = |v: f32x8| v.min(one).max(zero);
        let lane = f32x8::new([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let first = (xa as usize) & !7;
        for ly in ya..=yb {
            let my = f32x8::splat((y0 + ly - py) as f32);
            let row = ly as usize * TILE;
            let mut c = first;
            while c <= xb as usize {
                let k = row + c;
                let zr = f32x8::load(&self.recv[k..k + 8]);
                let valid = (zr - zr * bias).cmp_gt(zo);
                if valid.move_mask() != 0 {
                    let mx = f32x8::splat((x0 + c as i64 - px) as f32) + lane;
                    let q = (zo * zr) / (zr - zo);
                    let gx = (ax * q).min(cap);
                    let gy = (ay * q).min(cap);
                    let wx = sat(half - (mx - half) * gx) - sat(half - (mx + half) * gx);
                    let wy = sat(half - (my - half) * gy) - sat(half - (my + half) * gy);
                    add(k, valid.blend(wx * wy, zero));
                }
                c += 8;
            }
        }
    }
}

/// fp16 blending of 8 lanes (lanes adding 0 are left alone: blending
/// `x + 0` changes nothing).
#[inline]
fn blend_f16(acc: &mut [f16], occ: f32x8) {
    for (a, o) in acc.iter_mut().zip(occ.to_array()) {
        if o != 0.0 {
            *a = add_f16(*a, o);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_addition_rounds_like_the_hardware() {
        // 2048 + 1 = 2048 (the paper's example: a tie, to even).
        assert_eq!(add_f16(f16::from_f32(2048.0), 1.0).to_f32(), 2048.0);
        // The paper's 0.5 + 1/2049 = 0.5 holds only when rounding toward
        // zero; IEEE round-to-nearest gives 0.5 + 2^-11 (0.99 ulp rounds
        // up), and a sum stalls only below half an ulp.
        assert_eq!(
            add_f16(f16::from_f32(0.5), 1.0 / 2049.0).to_f32(),
            0.5 + 1.0 / 2048.0
        );
        assert_eq!(add_f16(f16::from_f32(0.5), 1.0 / 4097.0).to_f32(), 0.5);
        let up = add_f16(f16::from_f32(0.5), 1.0 / 4000.0).to_f32();
        assert_eq!(up, 0.5 + 1.0 / 2048.0);
        assert_eq!(batch_size(100), 10);
        assert_eq!(batch_size(10), 4);
        assert_eq!(batch_size(1), 1);
    }
}
