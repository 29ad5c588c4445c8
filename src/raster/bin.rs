//! Binning: which set-up triangles touch which screen tile, in submission
//! order (the order every tile then rasterizes them in, so results do not
//! depend on scheduling).

use super::framebuffer::{TileGrid, TILE_SIZE};

/// Triangle indices per tile, stored compactly (CSR).
#[derive(Debug, Clone, Default)]
pub struct TileBins {
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

impl TileBins {
    /// Bins triangles given their inclusive pixel bounding boxes.
    pub fn build(grid: &TileGrid, bboxes: impl Iterator<Item = [i32; 4]> + Clone) -> Self {
        let ts = TILE_SIZE as i32;
        let tiles = |b: [i32; 4]| {
            let (tx0, ty0) = ((b[0] / ts) as usize, (b[1] / ts) as usize);
            let (tx1, ty1) = ((b[2] / ts) as usize, (b[3] / ts) as usize);
            (ty0..=ty1).flat_map(move |ty| (tx0..=tx1).map(move |tx| ty * grid.tiles_x + tx))
        };
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
