//! Half-wedge membership, shared by every wedge-based pass (penumbra
//! wedges, blending, DCS, STSV): the per-light start (casters, hard
//! shadow volume counts from the centre), the light's bound, the raster
//! state and draw of both wedge sets, and the tile-local face count that
//! tells which receivers lie inside each half.

use crate::error::Result;
use crate::raster::{
    draw, CompareFunc, CullMode, FragmentBatch, FragmentStage, RasterState, TILE_PIXELS, TILE_SIZE,
};
use crate::scene::LightShape;
use crate::shadow::kit::light_frame::RectFrame;
use crate::shadow::kit::volumes::{build_volume, light_point, stencil_counts, ShadowVolume};
use crate::shadow::kit::wedge_geometry::{LightBound, WedgePrimitive, WedgeSet, Wedges};
use crate::shadow::{PassTiming, ShadowContext};
use rayon::prelude::*;
use std::time::Instant;

/// Marks "no half-wedge yet" in a tile.
pub const NONE: u32 = u32::MAX;

/// Which receivers of one tile lie inside one half-wedge: the half's face
/// count per pixel (exact `i32`), kept for one half at a time — a half's
/// triangles are contiguous and a tile sees them in order, so when the
/// next half starts the previous one is complete and can be drained.
pub struct HalfWedgeMembership {
    counts: Vec<i32>,
    current: u32,
    /// Touched rectangle of `counts` (local, inclusive min, exclusive max).
    touched: [usize; 4],
}

impl Default for HalfWedgeMembership {
    fn default() -> Self {
        Self::new()
    }
}

impl HalfWedgeMembership {
    /// No half yet, all counts zero.
    pub fn new() -> Self {
        HalfWedgeMembership {
            counts: vec![0; TILE_PIXELS],
            current: NONE,
            touched: [TILE_SIZE, TILE_SIZE, 0, 0],
        }
    }

    /// The half being counted.
    pub fn current(&self) -> Option<u32> {
        (self.current != NONE).then_some(self.current)
    }

    /// Counts one batch of a face of `prim`'s half, which becomes current
    /// (drain the previous one first). z-fail: faces behind the receiver
    /// count +1 leaving, −1 entering; z-pass: faces in front count +1
    /// entering, −1 leaving; so inside means a count of one either way.
    pub fn count(&mut self, batch: &FragmentBatch<0>, prim: WedgePrimitive, zpass: bool) {
        self.current = prim.half;
        let entering = if zpass { 1 } else { -1 };
        let delta = if batch.front_facing {
            entering
        } else {
            -entering
        } * prim.flip as i32;
        let lx = batch.local % TILE_SIZE;
        let ly = batch.local / TILE_SIZE;
        let mut lo = usize::MAX;
        let mut hi = 0;
        for k in batch.lanes() {
            self.counts[batch.local + k] += delta;
            lo = lo.min(lx + k);
            hi = hi.max(lx + k + 1);
        }
        let t = &mut self.touched;
        t[0] = t[0].min(lo);
        t[1] = t[1].min(ly);
        t[2] = t[2].max(hi);
        t[3] = t[3].max(ly + 1);
    }

    /// Calls `inside(local pixel)` for every pixel inside the current
    /// half, in row-major order, and resets for the next half.
    pub fn drain(&mut self, mut inside: impl FnMut(usize)) {
        let [x0, y0, x1, y1] = self.touched;
        for y in y0..y1 {
            for x in x0..x1 {
                let i = y * TILE_SIZE + x;
                if self.counts[i] == 1 {
                    inside(i);
                }
                self.counts[i] = 0;
            }
        }
        self.current = NONE;
        self.touched = [TILE_SIZE, TILE_SIZE, 0, 0];
    }
}

/// Raster state of the wedge pass, no writes. z-fail: every face behind
/// the receiver or at its depth — the tie rule of the z-fail stencil pass,
/// so the shared quad decides exactly as it did there; z-pass: strictly in
/// front, the exact complement of that test on the same fragment, so the
/// decision is again the stencil pass's.
pub fn wedge_state(zpass: bool) -> RasterState {
    RasterState {
        depth_func: if zpass {
            CompareFunc::Greater
        } else {
            CompareFunc::LessEqual
        },
        depth_write: false,
        stencil: None,
        cull: CullMode::None,
    }
}

/// Draws both sets of `wedges` (z-fail halves, then z-pass halves) into
/// `tiles` with the stage `stage_for(set, zpass)` builds, and after each
/// set calls `flush` on every tile so its last half is finished. Penumbra
/// wedges, blending and depth complexity sampling all count membership
/// this way; only what they do with a finished half differs.
pub fn draw_wedges<'w, S: FragmentStage<0>>(
    framebuffer: &mut crate::raster::Framebuffer,
    tiles: &mut [S::Target],
    wedges: &'w Wedges,
    stage_for: impl Fn(&'w WedgeSet, bool) -> S,
    flush: impl Fn(&S, &mut S::Target) + Sync,
) -> Result<()> {
    for (set, zpass) in [(&wedges.zfail, false), (&wedges.zpass, true)] {
        if set.triangles.is_empty() {
            continue;
        }
        let stage = stage_for(set, zpass);
        draw(
            framebuffer,
            tiles,
            &wedge_state(zpass),
            &set.vertices,
            &set.triangles,
            &stage,
        )?;
        tiles.par_iter_mut().for_each(|t| flush(&stage, t));
    }
    Ok(())
}

/// What every wedge-based technique starts a light with: the casters'
/// adjacency, the light's shape and centre, the stencil counts `D(O)` of
/// the hard shadow volumes from the centre, and the framebuffer (scene
/// depth) the wedges are then drawn against.
pub struct LightStart<'a> {
    /// Opaque casters.
    pub adj: &'a crate::geom::EdgeAdjacency,
    /// The light for wedge construction and integration.
    pub bound: LightBound,
    /// Its centre.
    pub point: glam::Vec3,
    /// Stencil count per pixel.
    pub counts: Vec<i32>,
    /// Scene depth.
    pub framebuffer: crate::raster::Framebuffer,
    /// The hard shadow volume the counts came from.
    pub volume: ShadowVolume,
}

/// Builds light `k`'s [`LightStart`], timing the shadow-volume pass.
pub fn light_start<'a>(
    ctx: &ShadowContext<'a>,
    k: usize,
    passes: &mut Vec<PassTiming>,
) -> Result<LightStart<'a>> {
    let light = &ctx.scene.lights[k];
    let point = light_point(&light.shape);
    let adj = ctx.cache.casters();
    let t = Instant::now();
    let volume = build_volume(&adj, ctx.view, point);
    let mut framebuffer = ctx.depth.clone();
    let counts = stencil_counts(&mut framebuffer, &volume, false)?;
    passes.push(PassTiming {
        name: format!("shadow volumes light {k}"),
        time: t.elapsed(),
    });
    Ok(LightStart {
        adj,
        bound: light_bound(&light.shape),
        point,
        counts,
        framebuffer,
        volume,
    })
}

/// The light's shape for wedge construction and integration.
pub fn light_bound(shape: &LightShape) -> LightBound {
    match *shape {
        LightShape::Rect { center, u, v, .. } => LightBound::Rect(RectFrame::new(
            center.as_dvec3(),
            u.as_dvec3(),
            v.as_dvec3(),
        )),
        LightShape::Sphere { center, radius } => LightBound::Sphere {
            center: center.as_dvec3(),
            radius: radius as f64,
        },
    }
}
