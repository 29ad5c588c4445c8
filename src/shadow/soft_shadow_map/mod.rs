//! Soft shadow maps (Atty, Holzschuch, Lapierre, Hasenfratz, Hansen and
//! Sillion 2006): per rect light, a depth map of the occluders from the
//! light's centre is turned into micro-patches (one per texel, parallel to
//! the light at the texel's depth); each patch's occlusion of the light,
//! seen from the receiver behind every soft-shadow-map texel inside its
//! penumbra extent, is summed into the soft shadow map (SSM), which each
//! receiver then looks up.
//!
//! - `geometry.rs`: the back-projection, the occlusion
//!   `(sat b − sat a)(sat d − sat c)`, the penumbra extent (derived there);
//! - `accumulate.rs`: binning to SSM tiles, per-tile accumulation in f32
//!   (SIMD), f16 or f16 in `⌊√M⌋` batches;
//! - here: the maps, the technique, the look-up.
//!
//! The SSM has the occluder map's texels plus a margin of the largest
//! penumbra reach on every side (the outer penumbra lies outside the
//! casters' window); its receivers are the receiver map's (objects with
//! `receive_shadows`, drawn through the same texels). A G-buffer point
//! looks the SSM up (nearest or bilinear) where the SSM's receiver is the
//! point's own surface; where it is not — the point is hidden from the
//! light's centre (self-shadowing: the casters are receivers too), or
//! between texel centres across a depth step — its occlusion is gathered
//! from the same patches at the exact point (docs/algorithms/soft-shadow-maps.md).

mod accumulate;
pub mod geometry;
pub mod options;

pub use accumulate::{add_f16, batch_size, Params, Patches, TILE};
pub use options::{Accumulate, Lookup, SsmOptions};

use crate::error::{Error, Result};
use crate::geom::SceneGeometry;
use crate::raster::{
    draw, CullMode, Framebuffer, NoFragmentStage, RasterState, TileGrid, FAR_DEPTH, MAX_SIDE,
    TILE_SIZE,
};
use crate::scene::{Light, LightShape, Scene};
use crate::shadow::kit::light_view::{
    depth_map, fully_lit, map_bounds, Bounds, LightView, MAX_DEPTH_TEXELS,
};
use crate::shadow::kit::shadow_maps::ShadowMapOptions;
use crate::shadow::kit::shadow_maps::{
    opaque_caster, per_receiver, project_receiver, DepthBias, MapReceiver,
};
use crate::shadow::kit::PassTimer;
use crate::shadow::technique::{Bands, Capabilities, Support, TechniqueInfo, TermKind};
use crate::shadow::{BufferNote, LightTerm, ShadowContext, ShadowOutput, ShadowTechnique};
use crate::view::{Extent, View};
use geometry::{patch_occlusion, reach};
use glam::Vec3;
use half::f16;
use rayon::prelude::*;

/// The soft-shadow-map technique.
#[derive(Debug, Clone, Copy)]
pub struct SoftShadowMap {
    /// Its own options.
    pub options: SsmOptions,
    /// The shared shadow-map options (map size, biases).
    pub map: ShadowMapOptions,
}

/// Soft shadow maps in the technique registry.
pub static TECHNIQUE: TechniqueInfo = TechniqueInfo {
    name: "soft-shadow-map",
    summary: "soft shadow maps (Atty et al. 2006): occluder-map texels as micro-patches back-projected onto the light, summed into a soft shadow map",
    module: "shadow/soft_shadow_map/",
    page: Some("soft-shadow-maps.md"),
    capabilities: |_| Capabilities {
        rect_lights: Support::Yes,
        sphere_lights: Support::Refused {
            param: "--technique",
            why: "a micro-patch's occlusion is the overlap of two axis-aligned rectangles \
                  (the patch back-projected onto a rectangular light); a sphere light has no \
                  such closed form (use dcs or reference)",
        },
        textured_lights: Support::Yes,
        enclosed_lights: crate::shadow::technique::MAPS_MISS_ENCLOSURE,
        // A micro-patch at the light's plane back-projects onto the whole
        // map (its reach grows as 1 / its depth from the light), so the
        // accumulation's work has no bound: found by a fuzz campaign as
        // minutes-long renders of 24 × 24 images.
        reached_lights: Support::Refused {
            param: "--technique",
            why: "its occluder texels back-project onto the light, and a caster at or beyond \
                  the light's plane would cover the whole map from every texel, without bound \
                  on the work (use penumbra-casting or reference, or move the caster away \
                  from the light)",
        },
        semi_opaque: Support::Ignored(
            "the occluder map holds opaque casters only; casters of constant opacity below 1 \
             cast no shadow here (use dcs or reference)",
        ),
        s_triangles: Support::StsvAddOn,
        output: TermKind::Vcoef,
        exact: false,
        exact_image: false,
    },
    quality_settings: |s| {
        let mut out = Vec::new();
        for passes in [1u8, 2] {
            let curve = if passes == 1 {
                "soft-shadow-map".to_string()
            } else {
                "soft-shadow-map 2 passes".to_string()
            };
            for size in [128u32, 256, 512, 1024] {
                let mut q = s.single(&curve, &format!("{size}² map"));
                q.options.shadow_map.map_size = size;
                q.options.ssm.ssm_passes = passes;
                out.push(q);
            }
        }
        out
    },
    build: |p| {
        Box::new(SoftShadowMap {
            options: p.options.ssm,
            map: p.options.shadow_map,
        })
    },
    // Per-pixel results from the pixel's own sample, the full-frame depth
    // buffer, the scene and per-pixel-keyed samples.
    bands: Bands::Rows,
    reads: {
        use crate::shadow::options::OptionGroup::*;
        &[ShadowMaps, Ssm]
    },
    cost: crate::shadow::technique::CostClass::Raster,
};

/// One light's soft shadow map and what was built for it.
#[derive(Debug, Clone)]
pub struct SsmLight {
    /// The SSM's view: the occluder map's texels plus the margin.
    pub view: View,
    /// Summed occlusion per SSM texel (row-major), merged over passes.
    pub ssm: Vec<f32>,
    /// The receiver's depth per SSM texel (`+∞`: none).
    pub receivers: Vec<f32>,
    /// The micro-patches of each pass (SSM texel coordinates).
    pub passes: Vec<Patches>,
    /// The accumulation's constants.
    pub params: Params,
    /// Occluder-map size in texels.
    pub occluder_size: (u32, u32),
    /// Margin of the SSM around the occluder map, texels per side.
    pub margin: (u32, u32),
    /// False when the margin was capped (outer penumbrae may be cut) or
    /// the light view could not hold every caster.
    pub complete: bool,
    /// Peak bytes of the maps, the SSM, the patches.
    pub bytes: u64,
}

impl SsmLight {
    /// Occlusion gathered at a receiver `(uv in SSM texels, depth)` from
    /// the same patches the SSM sums, in the same precision and order;
    /// patches count when `z_O < test_depth`.
    pub fn gather(&self, uv: (f64, f64), depth: f32, test_depth: f32) -> f32 {
        let prm = &self.params;
        let mut best = 0.0f32;
        for p in &self.passes {
            let zmin = p.min_depth;
            if !(zmin < test_depth) {
                continue;
            }
            let rx = reach(prm.hx_texels, 1.0, zmin as f64, depth as f64) + 1;
            let ry = reach(prm.hy_texels, 1.0, zmin as f64, depth as f64) + 1;
            let (cx, cy) = (uv.0.floor() as i64, uv.1.floor() as i64);
            let (y0, y1) = ((cy - ry).max(0), (cy + ry).min(prm.height as i64 - 1));
            let size = batch_size(p.len());
            let mut sum32 = 0.0f32;
            let (mut sum16, mut batch16, mut current) = (f16::ZERO, f16::ZERO, usize::MAX);
            for y in y0..=y1 {
                for i in p.row_range(y as usize, cx - rx, cx + rx) {
                    let z_o = p.depth[i];
                    if !(z_o < test_depth) {
                        continue;
                    }
                    let mx = (uv.0 - (p.x[i] as f64 + 0.5)) as f32;
                    let my = (uv.1 - (p.y[i] as f64 + 0.5)) as f32;
                    let occ = patch_occlusion(mx, my, z_o, depth, prm.ax, prm.ay);
                    if occ == 0.0 {
                        continue;
                    }
                    match prm.accumulate {
                        Accumulate::F32 => sum32 += occ,
                        Accumulate::F16 => sum16 = add_f16(sum16, occ),
                        Accumulate::F16Batched => {
                            let b = i / size;
                            if b != current {
                                sum16 = add_f16(sum16, batch16.to_f32());
                                batch16 = f16::ZERO;
                                current = b;
                            }
                            batch16 = add_f16(batch16, occ);
                        }
                    }
                }
            }
            let v = match prm.accumulate {
                Accumulate::F32 => sum32,
                Accumulate::F16 => sum16.to_f32(),
                Accumulate::F16Batched => add_f16(sum16, batch16.to_f32()).to_f32(),
            };
            if v > best {
                best = v;
            }
        }
        best
    }

    /// The occlusion of receiver `r` (projected into [`SsmLight::view`]):
    /// the SSM where its receiver is `r`'s surface, else gathered at `r`.
    pub fn occlusion(&self, r: &MapReceiver, lookup: Lookup) -> f32 {
        let (w, h) = (self.params.width as i64, self.params.height as i64);
        // The SSM's receiver is this point's surface when their depths
        // agree within twice the point's own bias (a neighbour texel on a
        // sloped receiver differs by about the slope bias).
        let tol = 2.0 * (r.depth - r.test_depth) + 1e-5 * r.depth;
        let texel = |x: i64, y: i64| -> Option<f32> {
            if x < 0 || y < 0 || x >= w || y >= h {
                return None;
            }
            let k = (y * w + x) as usize;
            let z = self.receivers[k] as f64;
            ((z - r.depth).abs() <= tol).then(|| self.ssm[k])
        };
        let found = match lookup {
            Lookup::Nearest => texel(r.uv.x.floor() as i64, r.uv.y.floor() as i64),
            Lookup::Bilinear => {
                let (sx, sy) = (r.uv.x - 0.5, r.uv.y - 0.5);
                let (x0, y0) = (sx.floor(), sy.floor());
                let (tx, ty) = ((sx - x0) as f32, (sy - y0) as f32);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let (mut sum, mut weight) = (0.0f32, 0.0f32);
                for (dx, dy, wgt) in [
                    (0, 0, (1.0 - tx) * (1.0 - ty)),
                    (1, 0, tx * (1.0 - ty)),
                    (0, 1, (1.0 - tx) * ty),
                    (1, 1, tx * ty),
                ] {
                    if let Some(v) = texel(x0 + dx, y0 + dy) {
                        sum += wgt * v;
                        weight += wgt;
                    }
                }
                (weight > 0.0).then(|| sum / weight)
            }
        };
        found.unwrap_or_else(|| self.gather((r.uv.x, r.uv.y), r.depth as f32, r.test_depth as f32))
    }
}

/// A rect light's half-sizes `(|u|, |v|)`, refusing parallelograms: the
/// occlusion is a product of two intervals only for a rectangle.
fn rect_half_sizes(light: &Light, k: usize) -> Result<(f64, f64)> {
    let LightShape::Rect { u, v, .. } = light.shape else {
        return Err(Error::param(
            "--technique",
            "soft-shadow-map needs rect lights (capabilities refuse sphere lights)",
        ));
    };
    let (u, v) = (u.as_dvec3(), v.as_dvec3());
    let (lu, lv) = (u.length(), v.length());
    if !(lu > 0.0 && lv > 0.0) || u.dot(v).abs() > 1e-6 * lu * lv {
        return Err(Error::param(
            "light",
            format!(
                "soft-shadow-map: light {k} is not a rectangle (u · v = {}); micro-patches are \
                 rectangles similar to the light only when u ⊥ v",
                u.dot(v)
            ),
        ));
    }
    Ok((lu, lv))
}

/// The nearest back faces' depth (front faces culled, closer wins): the
/// second pass's occluder map, drawn like the kit's [`depth_map`].
fn back_face_map(scene: &Scene, geometry: &SceneGeometry, view: &View) -> Result<Vec<f32>> {
    let keep = opaque_caster(scene, geometry);
    let grid = TileGrid::new(view.width, view.height)?;
    let triangles: Vec<[u32; 3]> = geometry
        .triangles
        .par_iter()
        .enumerate()
        .filter(|&(t, _)| keep(t as u32))
        .map(|(_, &tri)| tri)
        .collect();
    let vertices = crate::gbuffer::transform_vertices(geometry, view);
    let mut fb = Framebuffer::new(grid);
    let mut targets = vec![(); grid.tile_count()];
    let state = RasterState {
        cull: CullMode::Front,
        ..RasterState::default()
    };
    draw(
        &mut fb,
        &mut targets,
        &state,
        &vertices,
        &triangles,
        &NoFragmentStage,
    )?;
    let (w, h) = (view.width as usize, view.height as usize);
    let mut depth = vec![f32::INFINITY; w * h];
    let tiles = fb.tiles_mut();
    for (t, tile) in tiles.iter().enumerate() {
        let (x0, y0) = (
            (t % grid.tiles_x) * TILE_SIZE,
            (t / grid.tiles_x) * TILE_SIZE,
        );
        for r in 0..TILE_SIZE.min(h.saturating_sub(y0)) {
            for c in 0..TILE_SIZE.min(w - x0) {
                let d = tile.depth[r * TILE_SIZE + c];
                if d != FAR_DEPTH {
                    depth[(y0 + r) * w + x0 + c] = (view.near / d as f64) as f32;
                }
            }
        }
    }
    Ok(depth)
}

/// Builds light `k`'s soft shadow map; `Ok(None)` when nothing of the
/// casters is in front of the light's centre.
pub fn build_light(
    scene: &Scene,
    geometry: &SceneGeometry,
    k: usize,
    options: &SsmOptions,
    map: &ShadowMapOptions,
    casters: Bounds,
    receivers: Bounds,
) -> Result<Option<SsmLight>> {
    let light = &scene.lights[k];
    let (hx, hy) = rect_half_sizes(light, k)?;
    let LightShape::Rect { center, .. } = light.shape else {
        unreachable!("rect_half_sizes refuses other shapes");
    };
    let s = map.map_size;
    // The kit fits the window to the casters the receivers' cone (from the
    // centre) holds: right for a point light, but from the rest of an area
    // light casters outside that cone shadow receivers too. Fit to the
    // casters' whole projection instead (receivers ∪ casters).
    let fit_to = (receivers.0.min(casters.0), receivers.1.max(casters.1));
    let Some(first) = LightView::from_rect_light(light, center, casters, fit_to, (s, s))? else {
        return Ok(None);
    };
    // Texels similar to the light (§3.2): Δx / Δy = hx / hy.
    let win = first.view.window;
    let (ww, wh) = (win.right - win.left, win.top - win.bottom);
    let ratio = (ww / wh) * (hy / hx);
    let size = if ratio >= 1.0 {
        (s, ((s as f64 / ratio).round() as u32).clamp(1, s))
    } else {
        (((s as f64 * ratio).round() as u32).clamp(1, s), s)
    };
    let Some(lv) = LightView::from_rect_light(light, center, casters, fit_to, size)? else {
        return Ok(None);
    };
    let view = lv.view;
    let front = depth_map(geometry, opaque_caster(scene, geometry), &view)?;
    let back = if options.ssm_passes == 2 || options.ssm_bottom_patches {
        Some(back_face_map(scene, geometry, &view)?)
    } else {
        None
    };
    let zmin = front
        .as_slice()
        .iter()
        .chain(back.iter().flatten())
        .copied()
        .fold(f32::INFINITY, f32::min) as f64;
    let (dx, dy) = (ww / size.0 as f64, wh / size.1 as f64);
    // The receivers' deepest point bounds every penumbra's reach.
    let zmax_r = (0..8)
        .map(|c| {
            let (lo, hi) = receivers;
            let p = Vec3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            );
            view.depth_of(p.as_dvec3())
        })
        .fold(0.0f64, f64::max);
    let mut complete = lv.complete;
    let margin_of = |h: f64, d: f64, side: u32| -> (u32, bool) {
        if !(zmin.is_finite() && zmin < zmax_r) {
            return (0, true);
        }
        let m = (h * (1.0 / zmin - 1.0 / zmax_r) / d).ceil() + 1.0;
        // Capped at the map's own size per side (outer penumbrae beyond
        // are cut: only casters almost touching the light reach so far).
        let cap = side as f64;
        (m.min(cap) as u32, m <= cap)
    };
    let (mut ex, okx) = margin_of(hx, dx, size.0);
    let (mut ey, oky) = margin_of(hy, dy, size.1);
    complete &= okx && oky;
    // The SSM and receiver map must fit the light view's limits.
    while (size.0 + 2 * ex) > MAX_SIDE
        || (size.1 + 2 * ey) > MAX_SIDE
        || (size.0 + 2 * ex) as u64 * (size.1 + 2 * ey) as u64 > MAX_DEPTH_TEXELS
    {
        ex /= 2;
        ey /= 2;
        complete = false;
    }
    let (sw, sh) = (size.0 + 2 * ex, size.1 + 2 * ey);
    let near = view.near;
    let ssm_view = View::from_frustum(
        view.eye,
        view.forward,
        view.up,
        Extent::Window {
            left: (win.left - ex as f64 * dx) * near,
            right: (win.right + ex as f64 * dx) * near,
            bottom: (win.bottom - ey as f64 * dy) * near,
            top: (win.top + ey as f64 * dy) * near,
        },
        sw,
        sh,
        near,
    )?;
    let receives: Vec<bool> = scene.objects.iter().map(|o| o.receive_shadows).collect();
    let receiver_map = depth_map(
        geometry,
        |t| receives[geometry.triangle_object[t as usize] as usize],
        &ssm_view,
    )?;
    let bottom = back.as_deref().filter(|_| options.ssm_bottom_patches);
    let mut passes = vec![patches(front.as_slice(), bottom, size, (ex, ey), sh)];
    if options.ssm_passes == 2 {
        if let Some(b) = &back {
            passes.push(patches(b, None, size, (ex, ey), sh));
        }
    }
    let maps_bytes = front.memory_bytes() + back.as_ref().map_or(0, |b| b.len() as u64 * 4);
    drop((front, back));
    let params = Params {
        width: sw as usize,
        height: sh as usize,
        ax: (dx / (2.0 * hx)) as f32,
        ay: (dy / (2.0 * hy)) as f32,
        hx_texels: hx / dx,
        hy_texels: hy / dy,
        bias: map.depth_bias as f32,
        accumulate: options.ssm_accumulate,
    };
    let receivers_depth = receiver_map.as_slice().to_vec();
    drop(receiver_map);
    let refs: Vec<&Patches> = passes.iter().collect();
    let ssm = accumulate::soft_shadow_map(&params, &receivers_depth, &refs);
    let bytes = maps_bytes
        + 2 * (sw as u64 * sh as u64 * 4)
        + passes.iter().map(|p| p.memory_bytes()).sum::<u64>();
    Ok(Some(SsmLight {
        view: ssm_view,
        ssm,
        receivers: receivers_depth,
        passes,
        params,
        occluder_size: size,
        margin: (ex, ey),
        complete,
        bytes,
    }))
}

/// The micro-patches of an occluder map, in SSM texels (offset by the
/// margin), in patch order; with `bottom`, a second patch at the back
/// faces' depth under every outline texel (a 4-neighbour empty or deeper
/// than this texel's back face).
fn patches(
    front: &[f32],
    bottom: Option<&[f32]>,
    (w, h): (u32, u32),
    (ex, ey): (u32, u32),
    sh: u32,
) -> Patches {
    let at = |m: &[f32], x: u32, y: u32| m[(y * w + x) as usize];
    let mut p = Patches {
        row_start: vec![0; sh as usize + 1],
        ..Patches::default()
    };
    // A neighbour beyond this texel's back face (or empty) exposes the
    // occluder's side there: the texel is on the outline.
    let beyond = |x: i64, y: i64, zb: f32| {
        x < 0 || y < 0 || x >= w as i64 || y >= h as i64 || !(at(front, x as u32, y as u32) <= zb)
    };
    for y in 0..h {
        for x in 0..w {
            let z = at(front, x, y);
            if !z.is_finite() {
                continue;
            }
            p.x.push(x + ex);
            p.y.push(y + ey);
            p.depth.push(z);
            if let Some(b) = bottom {
                let (xi, yi) = (x as i64, y as i64);
                let zb = at(b, x, y);
                let outline = beyond(xi - 1, yi, zb)
                    || beyond(xi + 1, yi, zb)
                    || beyond(xi, yi - 1, zb)
                    || beyond(xi, yi + 1, zb);
                if outline && zb.is_finite() && zb > z {
                    p.x.push(x + ex);
                    p.y.push(y + ey);
                    p.depth.push(zb);
                }
            }
        }
        p.row_start[(y + ey) as usize + 1] = p.len() as u32;
    }
    // Rows without patches (margins) start where the previous row ended.
    for r in 1..p.row_start.len() {
        if p.row_start[r] < p.row_start[r - 1] {
            p.row_start[r] = p.row_start[r - 1];
        }
    }
    p.finish();
    p
}

impl ShadowTechnique for SoftShadowMap {
    fn name(&self) -> &'static str {
        "soft-shadow-map"
    }

    fn compute(&self, ctx: &ShadowContext) -> Result<ShadowOutput> {
        let bias: DepthBias = self.map.bias();
        bias.validate()?;
        let mut out = ShadowOutput::default();
        let n = ctx.gbuffer.len();
        // Nothing casts or nothing receives: every light fully visible.
        let Some((casters, receivers)) = map_bounds(ctx.scene) else {
            return Ok(fully_lit(ctx));
        };
        let width = ctx.gbuffer.width as usize;
        let mut peak = 0;
        let mut notes = Vec::new();
        for k in 0..ctx.scene.lights.len() {
            let t = PassTimer::start(format!("soft shadow map light {k}"));
            let built = build_light(
                ctx.scene,
                ctx.geometry,
                k,
                &self.options,
                &self.map,
                casters,
                receivers,
            )?;
            t.finish(&mut out.passes);
            let Some(ssm) = built else {
                out.lights.push(LightTerm::Vcoef(vec![1.0; n]));
                continue;
            };
            peak = peak.max(ssm.bytes);
            notes.push(format!(
                "light {k}: occluder map {}×{}, SSM {}×{} (margin {}×{}), {} patches{}",
                ssm.occluder_size.0,
                ssm.occluder_size.1,
                ssm.params.width,
                ssm.params.height,
                ssm.margin.0,
                ssm.margin.1,
                ssm.passes.iter().map(|p| p.len()).sum::<usize>(),
                if ssm.complete {
                    ""
                } else {
                    " (INCOMPLETE: casters cut by the light view or margin capped)"
                }
            ));
            let t = PassTimer::start(format!("soft shadow map look-up light {k}"));
            let view = ssm.view;
            let lookup = self.options.ssm_lookup;
            let vcoef = per_receiver(ctx.gbuffer, width, |_, _, g| {
                // Behind the light's plane: that side is not lit from the
                // centre's view (as hard shadow maps).
                if !(view.depth_of(g.position.as_dvec3()) > 0.0) {
                    return 0.0;
                }
                // Outside the SSM's window: beyond every penumbra.
                let Some(r) = project_receiver(g, &view, &bias) else {
                    return 1.0;
                };
                1.0 - ssm.occlusion(&r, lookup).clamp(0.0, 1.0)
            });
            t.finish(&mut out.passes);
            out.lights.push(LightTerm::Vcoef(vcoef));
        }
        out.buffers.push(BufferNote {
            name: "soft shadow maps".into(),
            detail: format!(
                "one light at a time: occluder map(s) (f32 linear depth), receiver map and SSM \
                 (f32 per texel), patch list and tile bins; {}",
                notes.join("; ")
            ),
            bytes: peak,
        });
        Ok(out)
    }
}
