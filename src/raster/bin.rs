//! Binning: which set-up triangles touch which screen tile, in submission
//! order (the order every tile then rasterizes them in, so results do not
//! depend on scheduling).

use super::framebuffer::{TileGrid, TILE_SIZE};
use super::setup::SetupTriangle;

/// Triangle indices per tile, stored compactly (CSR).
#[derive(Debug, Clone, Default)]
pub struct TileBins {
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

impl TileBins {
    /// Bins triangles: each goes to the tiles its bounding box covers and
    /// whose pixel centres are not all outside one of its edges (long thin
    /// triangles, such as shadow-volume sides, cross far fewer tiles than
    /// their boxes).
    pub fn build<const N: usize>(grid: &TileGrid, triangles: &[SetupTriangle<N>]) -> Self {
        let ts = TILE_SIZE as i32;
        let tiles = |t: &SetupTriangle<N>| {
            let b = t.bbox;
            let (tx0, ty0) = ((b[0] / ts) as usize, (b[1] / ts) as usize);
            let (tx1, ty1) = ((b[2] / ts) as usize, (b[3] / ts) as usize);
            let edges = t.edges;
            (ty0..=ty1)
                .flat_map(move |ty| (tx0..=tx1).map(move |tx| (tx, ty)))
                .filter(move |&(tx, ty)| {
                    let (x0, y0) = ((tx * TILE_SIZE) as i64, (ty * TILE_SIZE) as i64);
                    let last = TILE_SIZE as i64 - 1;
                    edges.iter().all(|e| {
                        let corner = e.at_pixel(x0, y0);
                        corner + (e.step_x() * last).max(0) + (e.step_y() * last).max(0) >= 0
                    })
                })
                .map(move |(tx, ty)| ty * grid.tiles_x + tx)
        };
        let bboxes = triangles.iter();
        let mut counts = vec![0u32; grid.tile_count() + 1];
        for b in bboxes.clone() {
            for t in tiles(b) {
                counts[t + 1] += 1;
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let mut fill = counts.clone();
        let mut triangles = vec![0u32; counts[grid.tile_count()] as usize];
        for (i, b) in bboxes.enumerate() {
            for t in tiles(b) {
                triangles[fill[t] as usize] = i as u32;
                fill[t] += 1;
            }
        }
        TileBins {
            offsets: counts,
            triangles,
        }
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
