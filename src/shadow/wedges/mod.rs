//! Penumbra wedges (Assarsson & Akenine-Möller 2003; thesis §3.1).
//!
//! Per light: the hard shadow volumes from the centre give the V-buffer's
//! integer start (the stencil count `w(c)`); then every silhouette edge's
//! wedge, split by its shadow-volume quad into an outer and an inner half,
//! is rasterized through the pipeline. Each half is a closed convex
//! polyhedron, so a receiver `p` is inside it exactly when the count of
//! its faces behind `p` (z-fail; leaving +1, entering −1) is one — or, for
//! halves the eye is provably outside of (with a margin for the near
//! plane), the count of its faces in front of `p` (z-pass): those never
//! need the faces behind the receivers, which depth bounds then skip
//! wholesale. The fragment stage keeps that count per
//! pixel in a tile-local buffer, one half at a time (a half's triangles
//! are contiguous and tiles see them in order), and when the next half
//! starts it integrates the previous one for every pixel inside it:
//! `V += ±m · |R_e(p)| / |A|` ([`region_fraction`]).
//! `Vcoef = 1 − clamp(V, 0, 1)`.

pub mod blend;
pub mod light_parts;

use super::kit::light_frame::{region_fraction, region_fraction_sphere};
use super::kit::membership::{draw_wedges, light_start, HalfSink, LightStart, MembershipTile};
use super::kit::tiles::{local_xy, TilePixels};
use super::kit::timing::PassTimer;
use super::kit::volumes::silhouette_quads;
use super::kit::wedge_geometry::{HalfWedge, LightBound, SilhouetteQuad, Wedges};
use super::technique::OPAQUE_ONLY;
use super::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use super::{LightTerm, PassTiming, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::error::Result;
use crate::gbuffer::GBuffer;
use crate::geom::silhouette::faces_point;
use crate::output::Layer;
use crate::raster::{TileGrid, TILE_PIXELS, TILE_SIZE};

/// The penumbra-wedge technique. S-triangles (opacity-textured casters)
/// are shadowed by the soft-textured-shadow-volume add-on the render
/// applies to its Vcoef (thesis §5.2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PenumbraWedges;

/// Penumbra wedges in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "wedges",
    summary: "penumbra wedges on the centre silhouettes: analytic Vcoef, over-shadows where silhouettes overlap (thesis §3.1)",
    module: "shadow/wedges/",
    page: Some("penumbra-wedges.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Yes,
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::SILHOUETTES_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| vec![s.single("wedges", "centre silhouettes")],
    build: |_| Box::new(PenumbraWedges),
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: &[],
    cost: crate::shadow::technique::CostClass::Raster,
};

/// One tile's state of the wedge pass (besides its membership counts).
///
/// Precisions: the membership count is an exact `i32`; the V-buffer is
/// `f32` (values are a small integer plus fractions; f32 keeps 2⁻²⁴
/// relative precision, far below a display's 2⁻⁸) accumulated in a fixed
/// order, so results do not depend on threads.
pub struct WedgeTile {
    tile: usize,
    vbuffer: Vec<f32>,
    halves_in: Vec<u32>,
    /// Blending only: the current silhouette's per-light-part buffer.
    parts: Vec<[light_parts::LightPart; 4]>,
    /// Blending only: the final per-light-part buffer.
    final_parts: Vec<[light_parts::LightPart; 4]>,
    /// Blending only: rectangle of `parts` that may be non-empty.
    parts_touched: [usize; 4],
}

impl WedgeTile {
    /// Tile `tile` of the pass, its V-buffer starting at `start`.
    fn new(tile: usize, start: impl Iterator<Item = f32>) -> MembershipTile<Self> {
        let mut vbuffer = vec![0.0; TILE_PIXELS];
        for (v, s) in vbuffer.iter_mut().zip(start) {
            *v = s;
        }
        MembershipTile::new(WedgeTile {
            tile,
            vbuffer,
            halves_in: vec![0; TILE_PIXELS],
            parts: Vec::new(),
            final_parts: Vec::new(),
            parts_touched: [TILE_SIZE, TILE_SIZE, 0, 0],
        })
    }
}

/// What the wedge pass does with a finished half-wedge: the edge
/// integral for every receiver inside it.
struct WedgeSink<'a> {
    gbuffer: &'a GBuffer,
    grid: TileGrid,
    halves: &'a [HalfWedge],
    light: LightBound,
    /// Accumulate into the tile's per-light-part buffer (blending).
    blend: bool,
}

impl HalfSink for WedgeSink<'_> {
    type Tile = WedgeTile;
    /// The half and the sign of its contribution.
    type Half = (HalfWedge, f64);

    fn half(&self, half: u32) -> (HalfWedge, f64) {
        let half = self.halves[half as usize];
        // Orientation of the light plane as seen from p decides which side
        // of the projected edge the centre is on for each half (see
        // `integrate`): outer halves see it on the unoccluded side.
        (half, if half.outer { 1.0 } else { -1.0 })
    }

    fn inside(&self, &(half, sign): &(HalfWedge, f64), tile: &mut WedgeTile, i: usize) {
        // Fragments never lie beyond the image (the rasterizer's scissor).
        let Some(i_global) = self.grid.tile_pixel(tile.tile, i) else {
            return;
        };
        if !self.gbuffer.is_surface(i_global) {
            return;
        }
        let g = self.gbuffer.sample(i_global);
        let p = g.position.as_dvec3();
        tile.halves_in[i] += 1;
        if self.blend {
            if let LightBound::Rect(frame) = &self.light {
                let facing = (frame.center - p).dot(frame.normal);
                light_parts::accumulate(
                    &mut tile.parts[i],
                    frame,
                    p,
                    &half,
                    sign * facing.signum(),
                );
                let (x, y) = local_xy(i);
                let t = &mut tile.parts_touched;
                *t = [t[0].min(x), t[1].min(y), t[2].max(x + 1), t[3].max(y + 1)];
            }
            return;
        }
        let r = match &self.light {
            LightBound::Rect(frame) => {
                let facing = (frame.center - p).dot(frame.normal);
                let c_side = sign * facing.signum();
                region_fraction(frame, p, half.q0, half.q1, c_side)
            }
            LightBound::Sphere { center, radius } => {
                region_fraction_sphere(*center, *radius, p, half.q0, half.q1)
            }
        };
        tile.vbuffer[i] += (sign * half.weight as f64 * r) as f32;
    }
}

/// Everything one light's wedge pass produced.
pub struct WedgeLight {
    /// The V-buffer per pixel (occluded fraction, unclamped).
    pub vbuffer: Vec<f32>,
    /// Half-wedges containing each pixel's receiver.
    pub halves_in: Vec<u32>,
    /// The wedges drawn.
    pub wedges: Wedges,
}

/// Runs the shadow volumes and the wedges of light `k`.
pub fn wedge_light(
    ctx: &ShadowContext,
    k: usize,
    passes: &mut Vec<PassTiming>,
) -> Result<WedgeLight> {
    let LightStart {
        adj,
        bound,
        point,
        counts,
        mut framebuffer,
        ..
    } = light_start(ctx, k, passes)?;

    let t = PassTimer::start(format!("wedge build light {k}"));
    let lit = faces_point(adj, point);
    let mut wedges = Wedges::default();
    for [a, b, m] in silhouette_quads(adj, &lit) {
        let quad = SilhouetteQuad {
            q0: adj.positions[a as usize],
            q1: adj.positions[b as usize],
            weight: m,
        };
        if !wedges.add(ctx.view, &bound, point, quad, None) {
            wedges.skipped += 1;
        }
    }
    t.finish(passes);

    let t = PassTimer::start(format!("wedges light {k}"));
    let grid: TileGrid = framebuffer.grid();
    let mut tiles: Vec<MembershipTile<WedgeTile>> = (0..grid.tile_count())
        .map(|tile| {
            let start = (0..TILE_PIXELS)
                .map(|i| grid.tile_pixel(tile, i).map_or(0.0, |g| counts[g] as f32));
            WedgeTile::new(tile, start)
        })
        .collect();
    draw_wedges(&mut framebuffer, &mut tiles, &wedges, |set, _| WedgeSink {
        gbuffer: ctx.gbuffer,
        grid,
        halves: &set.halves,
        light: bound,
        blend: false,
    })?;
    t.finish(passes);

    let mut vbuffer = vec![0.0f32; grid.width as usize * grid.height as usize];
    let mut halves_in = vec![0u32; vbuffer.len()];
    for (tile, t) in tiles.iter().enumerate() {
        grid.for_each_tile_pixel(tile, |i, g| {
            vbuffer[g] = t.data.vbuffer[i];
            halves_in[g] = t.data.halves_in[i];
        });
    }
    Ok(WedgeLight {
        vbuffer,
        halves_in,
        wedges,
    })
}

impl ShadowTechnique for PenumbraWedges {
    fn name(&self) -> &'static str {
        "wedges"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let mut out = ShadowOutput::default();
        let mut vlayer = Layer {
            name: "vbuffer".into(),
            channels: Vec::new(),
        };
        let mut wlayer = Layer {
            name: "wedges".into(),
            channels: Vec::new(),
        };
        for k in 0..ctx.scene.lights.len() {
            let w = wedge_light(ctx, k, &mut out.passes)?;
            let vcoef: Vec<f32> = w
                .vbuffer
                .iter()
                .zip(ctx.gbuffer.samples())
                .map(|(&v, g)| {
                    if g.is_surface() {
                        1.0 - v.clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect();
            out.lights.push(LightTerm::Vcoef(vcoef));
            vlayer.channels.push((k.to_string(), w.vbuffer));
            wlayer.channels.push((
                k.to_string(),
                w.halves_in.iter().map(|&n| n as f32).collect(),
            ));
        }
        out.layers.push(vlayer);
        out.layers.push(wlayer);
        Ok(out)
    }
}
