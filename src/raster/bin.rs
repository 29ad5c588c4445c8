//! Binning: which set-up triangles touch which screen tile, in submission
//! order (the order every tile then rasterizes them in, so results do not
//! depend on scheduling).

use super::framebuffer::{TileGrid, TILE_SIZE};
use super::setup::{QuadExtra, SetupTriangle};

/// Triangle indices per tile, stored compactly (CSR).
#[derive(Debug, Clone, Default)]
pub struct TileBins {
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

/// Appends `(tile, i)` for every tile triangle `i` of `triangles`
/// touches: the tiles its bounding box covers whose pixel centres are not
/// all outside one of its edges (long thin triangles, such as
/// shadow-volume sides, cross far fewer tiles than their boxes). Pairs
/// come in triangle order.
pub(crate) fn tile_pairs<const N: usize>(
    grid: &TileGrid,
    triangles: &[SetupTriangle<N>],
    quads: &[QuadExtra],
    out: &mut Vec<(u32, u32)>,
) {
    let shift = TILE_SIZE.trailing_zeros();
    let size = TILE_SIZE as i64;
    let last = size - 1;
    for (i, t) in triangles.iter().enumerate() {
        let index = i as u32;
        // Boxes are clamped to the screen: non-negative.
        let [x0, y0, x1, y1] = t.bbox.map(|v| (v as u32 >> shift) as usize);
        if x0 == x1 && y0 == y1 {
            out.push(((y0 * grid.tiles_x + x0) as u32, index));
            continue;
        }
        // Per edge, its largest value over a tile's pixel centres (at the
        // corner its slopes pick), at tile (x0, y0) and its steps from
        // tile to tile: exact integers, the same test tile by tile.
        // A quad's fourth edge is tested too; a triangle's fourth "edge"
        // is always inside.
        let fourth = quads.get(t.quad as usize).map(|q| q.edge);
        let edges = t.edges.iter().chain(fourth.iter());
        let mut row = [0i64; 4];
        let mut dx = [0i64; 4];
        let mut dy = [0i64; 4];
        for (k, e) in edges.enumerate() {
            let (sx, sy) = (e.step_x(), e.step_y());
            row[k] = e.at_pixel(x0 as i64 * size, y0 as i64 * size)
                + (sx * last).max(0)
                + (sy * last).max(0);
            dx[k] = sx * size;
            dy[k] = sy * size;
        }
        for ty in y0..=y1 {
            let mut v = row;
            for tx in x0..=x1 {
                if v[0] >= 0 && v[1] >= 0 && v[2] >= 0 && v[3] >= 0 {
                    out.push(((ty * grid.tiles_x + tx) as u32, index));
                }
                for k in 0..4 {
                    v[k] += dx[k];
                }
            }
            for k in 0..4 {
                row[k] += dy[k];
            }
        }
    }
}

impl TileBins {
    /// Bins triangles: each goes to the tiles its bounding box covers and
    /// whose pixel centres are not all outside one of its edges (long thin
    /// triangles, such as shadow-volume sides, cross far fewer tiles than
    /// their boxes).
    pub fn build<const N: usize>(grid: &TileGrid, triangles: &[SetupTriangle<N>]) -> Self {
        let mut pairs = Vec::with_capacity(triangles.len() * 2);
        tile_pairs(grid, triangles, &[], &mut pairs);
        Self::from_pairs(grid, &[pairs])
    }

    /// Bins from `(tile, triangle)` pairs, given as runs whose
    /// concatenation is in triangle order (a stable counting sort keeps
    /// that order inside every tile).
    pub(crate) fn from_pairs(grid: &TileGrid, runs: &[Vec<(u32, u32)>]) -> Self {
        let mut offsets = vec![0u32; grid.tile_count() + 1];
        for &(tile, _) in runs.iter().flatten() {
            offsets[tile as usize + 1] += 1;
        }
        for i in 1..offsets.len() {
            offsets[i] += offsets[i - 1];
        }
        let mut fill = offsets.clone();
        let mut triangles = vec![0u32; offsets[grid.tile_count()] as usize];
        for &(tile, tri) in runs.iter().flatten() {
            let slot = &mut fill[tile as usize];
            triangles[*slot as usize] = tri;
            *slot += 1;
        }
        TileBins { offsets, triangles }
    }

    /// The triangles binned to a tile, in submission order.
    pub fn tile(&self, tile: usize) -> &[u32] {
        &self.triangles[self.offsets[tile] as usize..self.offsets[tile + 1] as usize]
    }

    /// Total (triangle, tile) pairs.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when no triangle touches any tile.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}
