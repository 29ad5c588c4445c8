//! Penumbra-wedge blending (Forest et al. 2006; thesis §3.2,
//! `--technique wedge-blend`).
//!
//! Plain wedges add every silhouette's occlusion, so where penumbrae
//! overlap the overlap counts twice. Blending keeps, per receiver and per
//! quarter of the light (split at its centre), the occluded fraction and a
//! rectangle bounding the occluded region, first for one silhouette at a
//! time (the SV-buffer), then for everything blended so far (the
//! V-buffer). Merging a silhouette into the V-buffer subtracts the
//! *effective overlapped area* (EOAH, thesis eq. 3.1)
//! `ε = (A_v / B_v) · (A_s / B_s) · β`: the rectangles' intersection `β`,
//! weighted by how much of each rectangle is really occluded.
//!
//! What we do differently, and why:
//! - **Silhouettes = connected casters.** The thesis splits the silhouette
//!   into non-overlapping loops; we take each connected component of the
//!   casters' welded surface (one sphere, one box, one bunny). Its volume
//!   (its caps and sides) gives the SV-buffer's start, exactly as the
//!   whole volume gives plain wedges' (sub-volumes of the same triangles,
//!   so the shared-quad consistency holds per silhouette). A component
//!   whose own silhouette overlaps itself (a detailed model) keeps plain
//!   wedges' over-shadowing inside itself.
//! - **Rectangles exactly per edge.** The thesis builds the rectangle from
//!   outer half-wedges, then adjusts it with the largest X and Y of the
//!   occluding edges; we take, per quarter, the bounding box of each outer
//!   edge's region (union) and of the quarter minus each inner edge's
//!   region (intersection), from the same clipped polygons that give the
//!   areas. Outer halves of a silhouette are drawn before its inner ones,
//!   as the thesis requires (except across the z-fail / z-pass split, when
//!   the eye sits inside some wedge).
//! - **f32 per quantity**, not 8-bit packed; parts' occlusion is clamped
//!   to [0, 1] when blended (a quarter cannot be more than covered).
//! - Rect lights only (the quarters are the light's own); sphere lights
//!   are refused with a clear error.

use super::light_parts::{blend_part, to_f32, LightPart, EMPTY, QUARTERS};
use super::{WedgeSink, WedgeTile};
use crate::error::{Error, Result};
use crate::geom::silhouette::faces_point;
use crate::output::Layer;
use crate::raster::{TileGrid, TILE_PIXELS, TILE_SIZE};
use crate::shadow::kit::membership::{draw_wedges, light_bound, MembershipTile};
use crate::shadow::kit::tiles::{local_xy, TilePixels};
use crate::shadow::kit::timing::PassTimer;
use crate::shadow::kit::volumes::{
    build_volume, cap_triangles, light_point, side_quad, stencil_counts_of,
};
use crate::shadow::kit::wedge_geometry::{LightBound, SilhouetteQuad, Wedges};
use crate::shadow::technique::OPAQUE_ONLY;
use crate::shadow::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use rayon::prelude::*;

/// Penumbra-wedge blending in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "wedge-blend",
    summary: "penumbra-wedge blending: four light quarters, bounding rectangles, EOAH blending (thesis §3.2)",
    module: "shadow/wedges/blend.rs",
    page: Some("wedge-blending.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Refused {
            param: "--technique",
            why: "blending splits rect lights into quarters (use wedges or reference)",
        },
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::SILHOUETTES_MISS_ENCLOSURE,
        reached_lights: Support::Yes,
        semi_opaque: OPAQUE_ONLY,
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| vec![s.single("wedge-blend", "EOAH, 4 quarters")],
    build: |_| Box::new(WedgeBlending),
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: &[],
    cost: crate::shadow::technique::CostClass::Raster,
};

/// The penumbra-wedge blending technique. S-triangles are shadowed by
/// the soft-textured-shadow-volume add-on the render applies to its Vcoef.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WedgeBlending;

/// Connected components of the faces of `adj` (through shared edges):
/// a component id per face slot, and the count.
fn components(adj: &crate::geom::EdgeAdjacency) -> (Vec<u32>, usize) {
    let n = adj.face_vertices.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for e in 0..adj.edges.len() {
        let mut uses = adj.uses(e).iter();
        if let Some(first) = uses.next() {
            for u in uses {
                let (a, b) = (find(&mut parent, first.slot), find(&mut parent, u.slot));
                if a != b {
                    // Smaller root wins: ids do not depend on edge order
                    // beyond the adjacency's own (deterministic) order.
                    let (lo, hi) = (a.min(b), a.max(b));
                    parent[hi as usize] = lo;
                }
            }
        }
    }
    let mut id = vec![u32::MAX; n];
    let mut count = 0usize;
    let mut out = vec![0u32; n];
    for (slot, o) in out.iter_mut().enumerate() {
        let root = find(&mut parent, slot as u32) as usize;
        if id[root] == u32::MAX {
            id[root] = count as u32;
            count += 1;
        }
        *o = id[root];
    }
    (out, count)
}

impl ShadowTechnique for WedgeBlending {
    fn name(&self) -> &'static str {
        "wedge-blend"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let mut out = ShadowOutput::default();
        let mut wlayer = Layer {
            name: "wedges".into(),
            channels: Vec::new(),
        };
        for k in 0..ctx.scene.lights.len() {
            let light = &ctx.scene.lights[k];
            let bound = light_bound(&light.shape);
            let LightBound::Rect(_) = bound else {
                return Err(Error::param(
                    "--technique",
                    format!("wedge-blend: light {k} is a sphere; blending splits rect lights into quarters (use wedges or reference)"),
                ));
            };
            let point = light_point(&light.shape);
            let t = PassTimer::start(format!("volumes light {k}"));
            let adj = ctx.cache.casters();
            let lit = faces_point(adj, point);
            let volume = build_volume(adj, ctx.view, point);
            let (component, count) = components(adj);
            let n = adj.positions.len() as u32;
            let mut tris: Vec<Vec<[u32; 3]>> = vec![Vec::new(); count];
            for slot in 0..adj.face_vertices.len() {
                cap_triangles(adj, &lit, slot, n, &mut tris[component[slot] as usize]);
            }
            let mut quads: Vec<Vec<[u32; 3]>> = vec![Vec::new(); count];
            for e in 0..adj.edges.len() {
                if let Some(q) = side_quad(adj, &lit, e) {
                    let c = component[adj.uses(e)[0].slot as usize] as usize;
                    let [a, b, m] = q;
                    for _ in 0..m {
                        tris[c].push([a, b, b + n]);
                        tris[c].push([a, b + n, a + n]);
                    }
                    quads[c].push(q);
                }
            }
            t.finish_with(&mut out.passes, format!("{count} silhouettes"));

            let t = PassTimer::start(format!("wedge blending light {k}"));
            let mut framebuffer = ctx.depth.clone();
            let grid: TileGrid = framebuffer.grid();
            let width = grid.width as usize;
            let height = grid.height as usize;
            let mut tiles: Vec<MembershipTile<WedgeTile>> = (0..grid.tile_count())
                .map(|tile| {
                    let mut t = WedgeTile::new(tile, std::iter::empty());
                    t.data.parts = vec![[LightPart::default(); 4]; TILE_PIXELS];
                    t.data.final_parts = vec![[LightPart::default(); 4]; TILE_PIXELS];
                    t
                })
                .collect();
            for c in 0..count {
                if quads[c].is_empty() && tris[c].is_empty() {
                    continue;
                }
                // The silhouette's hard shadow starts its SV-buffer.
                let counts = stencil_counts_of(
                    &mut framebuffer,
                    &volume.vertices,
                    &tris[c],
                    volume.eye_outside,
                )?;
                tiles.par_iter_mut().enumerate().for_each(|(tile, t)| {
                    let t = &mut t.data;
                    grid.for_each_tile_pixel(tile, |i, g| {
                        let w = counts[g];
                        if w == 0 {
                            return;
                        }
                        for (part, quarter) in t.parts[i].iter_mut().zip(QUARTERS) {
                            part.occ = w as f32;
                            part.rect = if w > 0 { to_f32(quarter) } else { EMPTY };
                        }
                        let (lx, ly) = local_xy(i);
                        let r = &mut t.parts_touched;
                        *r = [
                            r[0].min(lx),
                            r[1].min(ly),
                            r[2].max(lx + 1),
                            r[3].max(ly + 1),
                        ];
                    });
                });
                // Its wedges, outer halves first.
                let mut wedges = Wedges::default();
                for outer in [true, false] {
                    for &[a, b, m] in &quads[c] {
                        let quad = SilhouetteQuad {
                            q0: adj.positions[a as usize],
                            q1: adj.positions[b as usize],
                            weight: m,
                        };
                        if !wedges.add(ctx.view, &bound, point, quad, Some(outer)) && outer {
                            wedges.skipped += 1;
                        }
                    }
                }
                draw_wedges(&mut framebuffer, &mut tiles, &wedges, |set, _| WedgeSink {
                    gbuffer: ctx.gbuffer,
                    grid,
                    halves: &set.halves,
                    light: bound,
                    blend: true,
                })?;
                // Blend the silhouette into the V-buffer and clear it.
                tiles.par_iter_mut().for_each(|t| {
                    let t = &mut t.data;
                    let [x0, y0, x1, y1] = t.parts_touched;
                    for y in y0..y1 {
                        for x in x0..x1 {
                            let i = y * TILE_SIZE + x;
                            for q in 0..4 {
                                let s = t.parts[i][q];
                                blend_part(&mut t.final_parts[i][q], &s);
                                t.parts[i][q] = LightPart::default();
                            }
                        }
                    }
                    t.parts_touched = [TILE_SIZE, TILE_SIZE, 0, 0];
                });
            }
            t.finish(&mut out.passes);

            let mut vcoef = vec![0.0f32; width * height];
            let mut halves_in = vec![0.0f32; width * height];
            for (tile, t) in tiles.iter().enumerate() {
                let t = &t.data;
                grid.for_each_tile_pixel(tile, |i, g| {
                    if ctx.gbuffer.is_surface(g) {
                        let occ: f32 = t.final_parts[i].iter().map(|p| p.occ).sum::<f32>() / 4.0;
                        vcoef[g] = 1.0 - occ.clamp(0.0, 1.0);
                        halves_in[g] = t.halves_in[i] as f32;
                    }
                });
            }
            out.lights.push(LightTerm::Vcoef(vcoef));
            wlayer.channels.push((k.to_string(), halves_in));
        }
        out.layers.push(wlayer);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shadow::kit::light_frame::RectFrame;
    use crate::shadow::kit::wedge_geometry::HalfWedge;
    use crate::shadow::wedges::light_parts::accumulate;
    use glam::DVec3;

    #[test]
    fn blending_disjoint_rectangles_adds_and_overlapping_full_ones_do_not() {
        // Two silhouettes covering disjoint halves of a quarter: no
        // overlap, plain sum.
        let mut v = LightPart::default();
        blend_part(
            &mut v,
            &LightPart {
                occ: 0.5,
                rect: [0.0, 0.0, 0.5, 1.0],
            },
        );
        blend_part(
            &mut v,
            &LightPart {
                occ: 0.5,
                rect: [0.5, 0.0, 1.0, 1.0],
            },
        );
        assert!((v.occ - 1.0).abs() < 1e-6);
        // The same fully covered rectangle twice: the overlap is all of it.
        let mut v = LightPart::default();
        let full = LightPart {
            occ: 0.25,
            rect: [0.0, 0.0, 0.5, 0.5],
        };
        blend_part(&mut v, &full);
        blend_part(&mut v, &full);
        assert!((v.occ - 0.25).abs() < 1e-6, "{}", v.occ);
    }

    #[test]
    fn quarters_of_an_edge_region_sum_to_the_whole() {
        let frame = RectFrame::new(
            DVec3::new(0.0, 4.0, 0.0),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.5),
        );
        let p = DVec3::ZERO;
        let half = HalfWedge {
            q0: DVec3::new(0.05, 2.0, -5.0),
            q1: DVec3::new(0.2, 2.0, 5.0),
            weight: 1,
            outer: true,
        };
        for side in [1.0, -1.0] {
            let whole =
                crate::shadow::kit::light_frame::region_fraction(&frame, p, half.q0, half.q1, side);
            let mut parts = [LightPart::default(); 4];
            accumulate(&mut parts, &frame, p, &half, side);
            let sum: f32 = parts.iter().map(|p| p.occ).sum::<f32>() / 4.0;
            assert!((sum as f64 - whole).abs() < 1e-6, "{sum} vs {whole}");
        }
    }
}
