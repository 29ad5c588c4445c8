//! Half-wedge membership, shared by every wedge-based pass (penumbra
//! wedges, blending, DCS, STSV): the per-light start (casters, hard
//! shadow volume counts from the centre), the light's bound, the raster
//! state and draw of both wedge sets, the tile-local face count that
//! tells which receivers lie inside each half, and the one fragment stage
//! ([`GroupedMembership`]) that counts it and hands every finished half to
//! a technique's [`HalfSink`].

use crate::error::Result;
use crate::raster::{
    draw, ClipVertex, CompareFunc, CullMode, FragmentBatch, FragmentStage, Framebuffer,
    RasterState, TILE_PIXELS, TILE_SIZE,
};
use crate::scene::LightShape;
use crate::shadow::kit::light_frame::RectFrame;
use crate::shadow::kit::tiles::local_xy;
use crate::shadow::kit::timing::PassTimer;
use crate::shadow::kit::volumes::{
    build_volume, light_point, stencil_count_shifts, stencil_counts, ShadowVolume,
};
use crate::shadow::kit::wedge_geometry::{LightBound, WedgePrimitive, WedgeSet, Wedges};
use crate::shadow::{PassTiming, ShadowContext};
use rayon::prelude::*;

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
        let (lx, ly) = local_xy(batch.local);
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

/// What a grouped-membership pass does with each finished half: penumbra
/// wedges integrate the edge over the light, DCS records (pixel, edge)
/// pairs, STSV tests the receivers against the S-triangle's planes.
pub trait HalfSink: Sync {
    /// The pass's own per-tile state (besides the membership counts).
    type Tile: Send;
    /// What [`HalfSink::inside`] needs of the finished half, looked up once
    /// per half and tile.
    type Half;

    /// Looks up the finished half `half` (its primitives' `half` index).
    fn half(&self, half: u32) -> Self::Half;

    /// Called for every local pixel of `tile` inside `half`, in
    /// row-major order.
    fn inside(&self, half: &Self::Half, tile: &mut Self::Tile, local: usize);
}

/// One tile of a grouped-membership pass: the half being counted and the
/// sink's own state.
pub struct MembershipTile<T> {
    /// The current half's face counts.
    pub membership: HalfWedgeMembership,
    /// The sink's state.
    pub data: T,
}

impl<T> MembershipTile<T> {
    /// No half yet, around `data`.
    pub fn new(data: T) -> Self {
        MembershipTile {
            membership: HalfWedgeMembership::new(),
            data,
        }
    }
}

/// The one grouped-membership fragment stage: counts each half's faces
/// per pixel ([`HalfWedgeMembership`]) and, when a tile's next half
/// starts, hands the previous one's inside pixels to `sink`.
pub struct GroupedMembership<'a, H> {
    /// The half of every triangle drawn.
    pub primitives: &'a [WedgePrimitive],
    /// The set is counted z-pass (faces in front of the receiver).
    pub zpass: bool,
    /// What is done with a finished half.
    pub sink: H,
}

impl<H: HalfSink> GroupedMembership<'_, H> {
    /// Finishes `tile`'s current half, if any: the draw's last half in
    /// each tile is only finished here.
    pub fn flush(&self, tile: &mut MembershipTile<H::Tile>) {
        let Some(current) = tile.membership.current() else {
            return;
        };
        let half = self.sink.half(current);
        let MembershipTile { membership, data } = tile;
        membership.drain(|i| self.sink.inside(&half, data, i));
    }
}

impl<H: HalfSink> FragmentStage<0> for GroupedMembership<'_, H> {
    type Target = MembershipTile<H::Tile>;

    fn shade(&self, batch: &FragmentBatch<0>, tile: &mut Self::Target) {
        let prim = self.primitives[batch.primitive as usize];
        if tile.membership.current() != Some(prim.half) {
            self.flush(tile);
        }
        tile.membership.count(batch, prim, self.zpass);
    }
}

/// Draws `triangles` (each half's contiguous) with `stage` into `tiles`,
/// then finishes every tile's last half.
pub fn draw_grouped<H: HalfSink>(
    framebuffer: &mut Framebuffer,
    tiles: &mut [MembershipTile<H::Tile>],
    vertices: &[ClipVertex<0>],
    triangles: &[[u32; 3]],
    stage: &GroupedMembership<H>,
) -> Result<()> {
    draw(
        framebuffer,
        tiles,
        &wedge_state(stage.zpass),
        vertices,
        triangles,
        stage,
    )?;
    tiles.par_iter_mut().for_each(|t| stage.flush(t));
    Ok(())
}

/// Draws both sets of `wedges` (z-fail halves, then z-pass halves) into
/// `tiles`, each with the sink `sink_for(set, zpass)` builds. Penumbra
/// wedges, blending and depth complexity sampling all count membership
/// this way; only what they do with a finished half differs.
pub fn draw_wedges<'w, H: HalfSink>(
    framebuffer: &mut Framebuffer,
    tiles: &mut [MembershipTile<H::Tile>],
    wedges: &'w Wedges,
    sink_for: impl Fn(&'w WedgeSet, bool) -> H,
) -> Result<()> {
    for (set, zpass) in [(&wedges.zfail, false), (&wedges.zpass, true)] {
        if set.triangles.is_empty() {
            continue;
        }
        let stage = GroupedMembership {
            primitives: &set.primitives,
            zpass,
            sink: sink_for(set, zpass),
        };
        draw_grouped(framebuffer, tiles, &set.vertices, &set.triangles, &stage)?;
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
    Ok(light_start_shifted(ctx, k, passes, &[])?.0)
}

/// [`light_start`], and from the same setup of the volume the change of
/// its counts under each depth scale of `shifts`
/// ([`stencil_count_shifts`]).
pub fn light_start_shifted<'a>(
    ctx: &ShadowContext<'a>,
    k: usize,
    passes: &mut Vec<PassTiming>,
    shifts: &[f32],
) -> Result<(LightStart<'a>, Vec<Vec<i32>>)> {
    let light = &ctx.scene.lights[k];
    let point = light_point(&light.shape);
    let adj = ctx.cache.casters();
    let t = PassTimer::start(format!("shadow volumes light {k}"));
    let volume = build_volume(adj, ctx.view, point);
    let mut framebuffer = ctx.depth.clone();
    let (counts, changes) = if shifts.is_empty() {
        (
            stencil_counts(&mut framebuffer, &volume, false)?,
            Vec::new(),
        )
    } else {
        // The plain counts last, so that the stencil is left holding
        // them, as a plain pass leaves it.
        let scales: Vec<Option<f32>> = shifts
            .iter()
            .map(|&s| Some(s))
            .chain(std::iter::once(None))
            .collect();
        let mut changes = stencil_count_shifts(&mut framebuffer, &volume, false, &scales)?;
        let counts = changes.pop().unwrap_or_default();
        (counts, changes)
    };
    t.finish(passes);
    Ok((
        LightStart {
            adj,
            bound: light_bound(&light.shape),
            point,
            counts,
            framebuffer,
            volume,
        },
        changes,
    ))
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
