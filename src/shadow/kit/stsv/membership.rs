//! Which receivers lie in which S-triangle's volume: every STSV of one
//! light rasterized through the pipeline against the scene depth, with
//! z-fail membership counting per volume (the kit's [`GroupedMembership`],
//! as the wedge passes count half-wedges), then the exact plane test (§5.1.3) on
//! the receiver's shadow-ray origin, which drops the volume's margin and
//! every other conservative extra.

use super::volume::{build_volumes, Stsv, VolumeParams};
use super::{STriangles, ShadowOrigin};
use crate::error::{Error, Result};
use crate::gbuffer::GBuffer;
use crate::raster::{ClipVertex, TileGrid};
use crate::scene::Scene;
use crate::shadow::kit::membership::{
    draw_grouped, light_bound, GroupedMembership, HalfSink, MembershipTile,
};
use crate::shadow::kit::tiles::TilePixels;
use crate::shadow::kit::wedge_geometry::WedgePrimitive;
use crate::shadow::ShadowContext;
use crate::view::View;

/// One light's `(pixel, S-triangle)` membership, per tile.
#[derive(Debug, Clone)]
pub struct StsvMembership {
    /// The tiles of the image.
    pub grid: TileGrid,
    /// Per tile: `local pixel << 32 | S-triangle index`, sorted, without
    /// duplicates (a receiver in both volumes of a two-sided S-triangle is
    /// listed once). Only surface pixels whose object receives shadows.
    pub tiles: Vec<Vec<u64>>,
    /// Volumes drawn.
    pub volumes: usize,
    /// Triangles drawn.
    pub triangles: usize,
    /// `(pixel, volume)` pairs the rasterizer found inside, before the
    /// exact plane test.
    pub raster_pairs: usize,
}

impl StsvMembership {
    /// No pairs, for `grid`.
    pub fn empty(grid: TileGrid) -> Self {
        StsvMembership {
            grid,
            tiles: vec![Vec::new(); grid.tile_count()],
            volumes: 0,
            triangles: 0,
            raster_pairs: 0,
        }
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.tiles.iter().map(Vec::len).sum()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.tiles.iter().all(Vec::is_empty)
    }

    /// Every pair as `(row-major pixel index, S-triangle index)`, tile by
    /// tile.
    pub fn pairs(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        let width = self.grid.width as usize;
        self.tiles
            .iter()
            .enumerate()
            .flat_map(move |(tile, entries)| {
                entries.iter().map(move |&e| {
                    let (x, y) = self.grid.tile_pixel_xy(tile, (e >> 32) as usize);
                    (y * width + x, e as u32)
                })
            })
    }

    /// Whether pixel `(x, y)` is in S-triangle `s`'s volume.
    pub fn contains(&self, x: u32, y: u32, s: u32) -> bool {
        if x >= self.grid.width || y >= self.grid.height {
            return false;
        }
        let (tile, local) = self.grid.locate(x, y);
        let key = (local as u64) << 32 | u64::from(s);
        self.tiles[tile].binary_search(&key).is_ok()
    }
}

/// One tile's state of the pass (besides its membership counts).
struct PairTile {
    tile: usize,
    entries: Vec<u64>,
    raster_pairs: usize,
}

/// What the pass does with a finished volume: tests the receivers inside
/// exactly.
struct VolumeSink<'a> {
    volumes: &'a [Stsv],
    grid: TileGrid,
    gbuffer: &'a GBuffer,
    scene: &'a Scene,
    origin: ShadowOrigin,
    tolerance: f64,
}

impl<'a> HalfSink for VolumeSink<'a> {
    type Tile = PairTile;
    type Half = &'a Stsv;

    fn half(&self, v: u32) -> &'a Stsv {
        &self.volumes[v as usize]
    }

    fn inside(&self, volume: &&'a Stsv, tile: &mut PairTile, i: usize) {
        tile.raster_pairs += 1;
        // Fragments never lie beyond the image (the rasterizer's scissor).
        let Some(global) = self.grid.tile_pixel(tile.tile, i) else {
            return;
        };
        if !self.gbuffer.is_surface(global) {
            return;
        }
        let g = self.gbuffer.sample(global);
        let receives = self
            .scene
            .objects
            .get(g.object as usize)
            .is_none_or(|o| o.receive_shadows);
        let o = self.origin.of(g.position, g.geo_normal).as_dvec3();
        if receives && volume.contains(o, self.tolerance) {
            tile.entries
                .push((i as u64) << 32 | u64::from(volume.s_triangle));
        }
    }
}

/// The volumes' triangles in clip space, volume after volume (a volume's
/// triangles contiguous, as [`GroupedMembership`] needs), each tagged
/// with its volume.
pub fn raster_mesh(
    view: &View,
    volumes: &[Stsv],
) -> (Vec<ClipVertex<0>>, Vec<[u32; 3]>, Vec<WedgePrimitive>) {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut primitives = Vec::new();
    for (v, volume) in volumes.iter().enumerate() {
        let base = vertices.len() as u32;
        vertices.extend(volume.vertices.iter().map(|p| ClipVertex {
            position: view.clip_point(p.as_vec3()),
            varyings: [],
        }));
        for t in &volume.triangles {
            triangles.push(t.map(|i| i + base));
            primitives.push(WedgePrimitive {
                half: v as u32,
                flip: 1,
            });
        }
    }
    (vertices, triangles, primitives)
}

/// The membership of light `light_index`'s volumes of `stris` over the
/// context's receivers. Errors: a light index out of range, or a draw
/// error (a depth buffer that does not match the view).
pub fn membership(
    ctx: &ShadowContext,
    light_index: usize,
    stris: &STriangles,
) -> Result<StsvMembership> {
    let light = ctx.scene.lights.get(light_index).ok_or_else(|| {
        Error::param(
            "light",
            format!(
                "light {light_index} does not exist (the scene has {})",
                ctx.scene.lights.len()
            ),
        )
    })?;
    let grid = ctx.depth.grid();
    if stris.is_empty() {
        return Ok(StsvMembership::empty(grid));
    }
    let params = VolumeParams::new(ctx.scene, ctx.geometry, ctx.view);
    let volumes = build_volumes(stris, &light_bound(&light.shape), &params);
    let (vertices, triangles, primitives) = raster_mesh(ctx.view, &volumes);
    let mut tiles: Vec<MembershipTile<PairTile>> = (0..grid.tile_count())
        .map(|tile| {
            MembershipTile::new(PairTile {
                tile,
                entries: Vec::new(),
                raster_pairs: 0,
            })
        })
        .collect();
    let stage = GroupedMembership {
        primitives: &primitives,
        zpass: false,
        sink: VolumeSink {
            volumes: &volumes,
            grid,
            gbuffer: ctx.gbuffer,
            scene: ctx.scene,
            origin: ShadowOrigin::new(ctx.scene, ctx.geometry),
            tolerance: params.tolerance,
        },
    };
    if !triangles.is_empty() {
        // The depth buffer is only read (no depth or stencil writes).
        let mut framebuffer = ctx.depth.clone();
        draw_grouped(&mut framebuffer, &mut tiles, &vertices, &triangles, &stage)?;
    }
    let mut out = StsvMembership::empty(grid);
    out.volumes = volumes.len();
    out.triangles = triangles.len();
    for (slot, MembershipTile { data: mut t, .. }) in out.tiles.iter_mut().zip(tiles) {
        t.entries.sort_unstable();
        t.entries.dedup();
        out.raster_pairs += t.raster_pairs;
        *slot = t.entries;
    }
    Ok(out)
}
