//! Tile-local pixels to image pixels, for every technique that keeps
//! per-tile buffers (the pipeline's 64×64 tiles, row-major inside).

use crate::raster::{TileGrid, TILE_PIXELS, TILE_SIZE};

/// Tile-local coordinates `(x, y)` of local pixel `local` (row-major,
/// [`TILE_SIZE`] per row).
#[inline]
pub fn local_xy(local: usize) -> (usize, usize) {
    (local % TILE_SIZE, local / TILE_SIZE)
}

/// Maps a tile's local pixel indices to image pixels.
pub trait TilePixels {
    /// Image coordinates `(x, y)` of local pixel `local` of `tile`, which
    /// may lie beyond the image's right or bottom edge in edge tiles.
    fn tile_pixel_xy(&self, tile: usize, local: usize) -> (usize, usize);

    /// Row-major image index of local pixel `local` of `tile`, or `None`
    /// beyond the image.
    fn tile_pixel(&self, tile: usize, local: usize) -> Option<usize>;

    /// Calls `f(local, image index)` for every pixel of `tile` inside the
    /// image, in local row-major order.
    fn for_each_tile_pixel(&self, tile: usize, f: impl FnMut(usize, usize));
}

impl TilePixels for TileGrid {
    #[inline]
    fn tile_pixel_xy(&self, tile: usize, local: usize) -> (usize, usize) {
        let (ox, oy) = self.tile_origin(tile);
        let (x, y) = local_xy(local);
        (ox as usize + x, oy as usize + y)
    }

    #[inline]
    fn tile_pixel(&self, tile: usize, local: usize) -> Option<usize> {
        let (x, y) = self.tile_pixel_xy(tile, local);
        let (w, h) = (self.width as usize, self.height as usize);
        (x < w && y < h).then_some(y * w + x)
    }

    fn for_each_tile_pixel(&self, tile: usize, mut f: impl FnMut(usize, usize)) {
        for local in 0..TILE_PIXELS {
            if let Some(i) = self.tile_pixel(tile, local) {
                f(local, i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_image_pixel_is_one_tile_pixel() {
        let grid = TileGrid::new(130, 67).expect("grid");
        let mut seen = vec![0u32; 130 * 67];
        for tile in 0..grid.tile_count() {
            grid.for_each_tile_pixel(tile, |local, i| {
                seen[i] += 1;
                let (x, y) = (i % 130, i / 130);
                assert_eq!(grid.locate(x as u32, y as u32), (tile, local));
            });
        }
        assert!(seen.iter().all(|&n| n == 1));
    }
}
