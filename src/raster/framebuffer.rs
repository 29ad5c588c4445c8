//! Tile-major buffers: the depth/stencil framebuffer and typed render
//! targets of any element type.
//!
//! Everything is stored tile by tile (64×64 pixels, row-major inside a
//! tile) so a tile's depth, stencil and targets are contiguous and stay in
//! cache while one thread rasterizes that tile.

use super::setup::MAX_SIDE;
use crate::error::{Error, Result};
use rayon::prelude::*;

/// Tile side in pixels.
pub const TILE_SIZE: usize = 64;
/// Pixels per tile.
pub const TILE_PIXELS: usize = TILE_SIZE * TILE_SIZE;
/// Depth and stencil tiles are this much longer than a tile: a batch of 8
/// lanes may start at any column and run past the row's (and the tile's)
/// end with its extra lanes masked off.
const TILE_PADDING: usize = super::simd::LANES;

/// How an image of `width × height` pixels is cut into tiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileGrid {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Tiles per row.
    pub tiles_x: usize,
    /// Tile rows.
    pub tiles_y: usize,
}

impl TileGrid {
    /// The grid for an image; refuses sizes the rasterizer cannot address.
    pub fn new(width: u32, height: u32) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(Error::param(
                "width/height",
                format!("{width}×{height} is outside 1..={MAX_SIDE} pixels per side"),
            ));
        }
        Ok(TileGrid {
            width,
            height,
            tiles_x: (width as usize).div_ceil(TILE_SIZE),
            tiles_y: (height as usize).div_ceil(TILE_SIZE),
        })
    }

    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.tiles_x * self.tiles_y
    }

    /// Pixel coordinates of a tile's top-left corner.
    pub fn tile_origin(&self, tile: usize) -> (i32, i32) {
        (
            ((tile % self.tiles_x) * TILE_SIZE) as i32,
            ((tile / self.tiles_x) * TILE_SIZE) as i32,
        )
    }

    /// (tile index, index inside the tile) of pixel `(x, y)`.
    #[inline]
    pub fn locate(&self, x: u32, y: u32) -> (usize, usize) {
        let (x, y) = (x as usize, y as usize);
        let tile = (y / TILE_SIZE) * self.tiles_x + x / TILE_SIZE;
        (tile, (y % TILE_SIZE) * TILE_SIZE + x % TILE_SIZE)
    }
}

/// A per-pixel render target of any `Copy` type, stored tile-major.
///
/// This is what fragment stages write besides depth and stencil: G-buffer
/// channels, per-pixel counters, bit masks, ...
#[derive(Debug, Clone)]
pub struct TiledTarget<T> {
    grid: TileGrid,
    tiles: Vec<Box<[T]>>,
}

impl<T: Copy + Send + Sync> TiledTarget<T> {
    /// A target filled with `value`.
    pub fn new(grid: TileGrid, value: T) -> Self {
        TiledTarget {
            grid,
            tiles: (0..grid.tile_count())
                .map(|_| vec![value; TILE_PIXELS].into_boxed_slice())
                .collect(),
        }
    }

    /// The grid.
    pub fn grid(&self) -> TileGrid {
        self.grid
    }

    /// Value at pixel `(x, y)`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> T {
        let (t, i) = self.grid.locate(x, y);
        self.tiles[t][i]
    }

    /// Sets pixel `(x, y)`.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, value: T) {
        let (t, i) = self.grid.locate(x, y);
        self.tiles[t][i] = value;
    }

    /// Sets every pixel.
    pub fn fill(&mut self, value: T) {
        for t in &mut self.tiles {
            t.fill(value);
        }
    }

    /// One tile's pixels (row-major, 64 per row, including the part of edge
    /// tiles outside the image).
    pub fn tile(&self, tile: usize) -> &[T] {
        &self.tiles[tile]
    }

    /// All tiles, mutably, for per-tile parallel passes.
    pub fn tiles_mut(&mut self) -> &mut [Box<[T]>] {
        &mut self.tiles
    }

    /// Row-major copy of the image (row 0 at the top).
    pub fn to_image(&self) -> Vec<T> {
        let mut out = Vec::with_capacity(self.grid.width as usize * self.grid.height as usize);
        for y in 0..self.grid.height {
            for x in 0..self.grid.width {
                out.push(self.get(x, y));
            }
        }
        out
    }
}

/// One tile of the depth/stencil framebuffer.
#[derive(Debug, Clone)]
pub struct DepthStencilTile {
    /// f32 depth (reversed Z, see [`super::RasterState`]). f32 because the
    /// depth is `near / w`: a float keeps constant relative precision from
    /// the near plane to infinity, where fixed-point depth would not.
    pub depth: Box<[f32]>,
    /// i32 stencil counts, allocated only once a pass uses the stencil.
    pub stencil: Option<Box<[i32]>>,
    /// Per depth scale of a shift-counting pass
    /// ([`super::draw_depth_shift_counts`]), the change of the stencil's
    /// count under that scale (i32, as the counts); empty otherwise.
    pub shifted: Vec<Box<[i32]>>,
}

/// The depth/stencil framebuffer.
#[derive(Debug, Clone)]
pub struct Framebuffer {
    grid: TileGrid,
    tiles: Vec<DepthStencilTile>,
}

/// Depth value of "nothing drawn yet": infinitely far in reversed Z.
pub const FAR_DEPTH: f32 = 0.0;

impl Framebuffer {
    /// A framebuffer cleared to [`FAR_DEPTH`], with no stencil yet.
    pub fn new(grid: TileGrid) -> Self {
        Framebuffer {
            grid,
            tiles: (0..grid.tile_count())
                .map(|_| DepthStencilTile {
                    depth: vec![FAR_DEPTH; TILE_PIXELS + TILE_PADDING].into_boxed_slice(),
                    stencil: None,
                    shifted: Vec::new(),
                })
                .collect(),
        }
    }

    /// The grid.
    pub fn grid(&self) -> TileGrid {
        self.grid
    }

    /// Clears the stencil of every tile to `value` (allocating it), tiles
    /// in parallel.
    pub fn clear_stencil(&mut self, value: i32) {
        self.tiles
            .par_iter_mut()
            .for_each(|t| match &mut t.stencil {
                Some(s) => s.fill(value),
                None => {
                    t.stencil = Some(vec![value; TILE_PIXELS + TILE_PADDING].into_boxed_slice())
                }
            });
    }

    /// Clears depth to `value`.
    pub fn clear_depth(&mut self, value: f32) {
        for t in &mut self.tiles {
            t.depth.fill(value);
        }
    }

    /// Replaces every depth value `d` by `f(d)` (tiles in parallel).
    pub fn map_depth(&mut self, f: impl Fn(f32) -> f32 + Sync) {
        self.tiles.par_iter_mut().for_each(|t| {
            for d in t.depth.iter_mut() {
                *d = f(*d);
            }
        });
    }

    /// Depth at pixel `(x, y)`.
    pub fn depth(&self, x: u32, y: u32) -> f32 {
        let (t, i) = self.grid.locate(x, y);
        self.tiles[t].depth[i]
    }

    /// Stencil at pixel `(x, y)` (0 if no stencil was ever allocated).
    pub fn stencil(&self, x: u32, y: u32) -> i32 {
        let (t, i) = self.grid.locate(x, y);
        self.tiles[t].stencil.as_ref().map_or(0, |s| s[i])
    }

    /// Row-major stencil counts of the whole image (row 0 at the top), 0
    /// where no stencil was ever allocated. Copied tile row by tile row,
    /// rows of tiles in parallel.
    pub fn stencil_image(&self) -> Vec<i32> {
        self.image_of(|t| t.stencil.as_deref())
    }

    /// Gives every tile `n` zeroed images of count changes
    /// ([`DepthStencilTile::shifted`]; `0` frees them), tiles in parallel.
    pub(crate) fn clear_shifted(&mut self, n: usize) {
        self.tiles.par_iter_mut().for_each(|t| {
            t.shifted.truncate(n);
            for s in &mut t.shifted {
                s.fill(0);
            }
            while t.shifted.len() < n {
                t.shifted
                    .push(vec![0; TILE_PIXELS + TILE_PADDING].into_boxed_slice());
            }
        });
    }

    /// Change image `k` of a shift-counting pass, row-major (0 where a
    /// tile has none).
    pub(crate) fn shifted_image(&self, k: usize) -> Vec<i32> {
        self.image_of(|t| t.shifted.get(k).map(|s| &s[..]))
    }

    /// A per-tile `i32` buffer (`TILE_SIZE`-wide rows) as one row-major
    /// image, 0 where a tile has none.
    fn image_of(&self, buffer: impl Fn(&DepthStencilTile) -> Option<&[i32]> + Sync) -> Vec<i32> {
        let (w, h) = (self.grid.width as usize, self.grid.height as usize);
        let mut out = vec![0; w * h];
        out.par_chunks_mut(w * TILE_SIZE)
            .enumerate()
            .for_each(|(ty, band)| {
                let rows = band.len() / w;
                for tx in 0..self.grid.tiles_x {
                    let t = ty * self.grid.tiles_x + tx;
                    let Some(values) = buffer(&self.tiles[t]) else {
                        continue;
                    };
                    let x0 = tx * TILE_SIZE;
                    let cols = TILE_SIZE.min(w - x0);
                    for r in 0..rows {
                        let dst = r * w + x0;
                        band[dst..dst + cols]
                            .copy_from_slice(&values[r * TILE_SIZE..r * TILE_SIZE + cols]);
                    }
                }
            });
        out
    }

    /// The tiles, mutably.
    pub(crate) fn tiles_mut(&mut self) -> &mut [DepthStencilTile] {
        &mut self.tiles
    }

    /// A tile.
    pub fn tile(&self, tile: usize) -> &DepthStencilTile {
        &self.tiles[tile]
    }
}
