//! Views from a point on a light, and the depth of the shadow casters seen
//! from any view, drawn by our own rasterizer: what shadow-map techniques
//! start from.
//!
//! A [`LightView`] is a perspective [`View`] from a point on a light whose
//! frustum is fitted to the casters that can shadow a receiver from that
//! point: their bounding box, cut to the half-space the point emits into,
//! projected from the point and intersected with the receivers' box
//! projected the same way (a caster point outside the receivers' cone casts
//! its shadow on nothing). [`depth_map`] then draws the casters' triangles
//! through [`crate::raster`] with the G-buffer's depth-only setup and keeps
//! one linear `f32` depth per texel.

use crate::error::{Error, Result};
use crate::geom::SceneGeometry;
use crate::raster::{
    draw, Framebuffer, NoFragmentStage, RasterState, TileGrid, FAR_DEPTH, MAX_SIDE, TILE_SIZE,
};
use crate::scene::{Light, LightShape, Scene};
use crate::shadow::{LightTerm, ShadowContext, ShadowOutput};
use crate::view::{Extent, View};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Largest tangent of a light view's half-angles (about 86.4°): a single
/// perspective view cannot hold a whole hemisphere, and texels beyond this
/// angle are stretched more than 250-fold. Casters that would need more are
/// cut off, and [`LightView::complete`] says so.
pub const MAX_TAN: f64 = 16.0;

/// Most texels a depth map may have (8192 × 8192: 256 MiB of `f32`, twice
/// that while drawing). Larger sizes are refused before anything is
/// allocated.
pub const MAX_DEPTH_TEXELS: u64 = 1 << 26;

/// The near distance is never below this fraction of the distance from the
/// point on the light to the farthest corner of the fitted bounds: casters
/// touching the light's plane are cut there rather than dividing by zero.
const MIN_NEAR: f64 = 1e-6;

/// Relative padding of the fitted window, so that the boundary of the
/// bounds is inside the frustum in spite of rounding.
const WINDOW_PAD: f64 = 1e-6;

/// Axis-aligned bounds, `(min, max)`, as [`Scene::bounds`] returns them.
pub type Bounds = (Vec3, Vec3);

/// A perspective view from a point on a light, fitted to the casters.
#[derive(Debug, Clone, Copy)]
pub struct LightView {
    /// The view: eye at the point on the light, off-axis window.
    pub view: View,
    /// Whether the frustum holds every point of the casters' bounds that
    /// lies in the half-space the point emits into and inside the
    /// receivers' cone. False when the bounds come closer to the point's
    /// emitting plane than the near distance allows (they touch or
    /// straddle it) or need a half-angle beyond [`MAX_TAN`]; the cut-off
    /// casters are then missing from a depth map of this view.
    pub complete: bool,
}

impl LightView {
    /// A view from `point_on_light` on a rect light looking along its
    /// emitting normal `normalize(cross(u, v))` (the texture's `v` is the
    /// view's up). A two-sided light emits both ways; the view looks to
    /// the side of the casters' bounds' centre (a single perspective view
    /// sees one side).
    ///
    /// The frustum is fitted to the casters' bounds cut to the emitting
    /// half-space, intersected with the receivers' bounds cut the same way,
    /// both projected from the point: nothing outside it can shadow a
    /// receiver from this point. The near distance is half the casters'
    /// nearest distance along the normal (at least 1e-6 of the
    /// bounds' reach), so no caster in front of the light is clipped unless
    /// it touches the light's plane. `Ok(None)` when nothing of the casters
    /// or the receivers is in front of the point: it shadows nothing.
    pub fn from_rect_light(
        light: &Light,
        point_on_light: Vec3,
        casters_bounds: Bounds,
        receivers_bounds: Bounds,
        size: (u32, u32),
    ) -> Result<Option<LightView>> {
        let LightShape::Rect {
            center,
            u,
            v,
            two_sided,
        } = light.shape
        else {
            return Err(Error::param("light", "from_rect_light needs a rect light"));
        };
        check_size(size)?;
        let (c, u, v) = (center.as_dvec3(), u.as_dvec3(), v.as_dvec3());
        let p = check_point(point_on_light)?;
        // Local coordinates of the point on the parallelogram.
        let n = u.cross(v);
        let (su, sv) = (v.cross(n), n.cross(u));
        let d = p - c;
        let (a, b) = (d.dot(su) / su.dot(u), d.dot(sv) / sv.dot(v));
        let off = d.dot(n) / n.length();
        let slack = 1e-4;
        if !(a.abs() <= 1.0 + slack
            && b.abs() <= 1.0 + slack
            && off.abs() <= slack * u.length().max(v.length()))
        {
            return Err(Error::param(
                "point_on_light",
                format!("{point_on_light} is not on the rect light"),
            ));
        }
        let mut normal = n.normalize();
        if two_sided {
            let (lo, hi) = check_bounds("casters_bounds", casters_bounds)?;
            if normal.dot(0.5 * (lo + hi) - p) < 0.0 {
                normal = -normal;
            }
        }
        fit(
            p,
            normal,
            Some(normal),
            v.normalize(),
            casters_bounds,
            receivers_bounds,
            size,
        )
    }

    /// A view from `point_on_light` on a sphere light looking toward the
    /// casters' bounds: along the mean of the unit directions to the
    /// corners of the bounds cut to the point's emitting half-space (the
    /// outside of the sphere's tangent plane there).
    ///
    /// The frustum is fitted as in [`LightView::from_rect_light`]: the cut
    /// casters' bounds ∩ the cut receivers' bounds, projected from the
    /// point, near at half the casters' nearest distance along the view
    /// direction. `Ok(None)` when nothing of either is in front of the
    /// tangent plane.
    pub fn from_sphere_light(
        light: &Light,
        point_on_light: Vec3,
        casters_bounds: Bounds,
        receivers_bounds: Bounds,
        size: (u32, u32),
    ) -> Result<Option<LightView>> {
        let LightShape::Sphere { center, radius } = light.shape else {
            return Err(Error::param(
                "light",
                "from_sphere_light needs a sphere light",
            ));
        };
        check_size(size)?;
        let p = check_point(point_on_light)?;
        let (c, r) = (center.as_dvec3(), radius as f64);
        let d = p - c;
        // A point on the sphere computed in f64 is rounded to f32 (the
        // caller's `Vec3`): off the sphere by up to half the f32 spacing at
        // the centre per coordinate, which is more than the radius itself
        // for a sphere of radius 1e-9 at 4. The check allows that rounding.
        let noise =
            4.0 * f64::from(f32::EPSILON) * c.abs().max_element().max(p.abs().max_element());
        if !((d.length() - r).abs() <= 1e-4 * r + noise) {
            return Err(Error::param(
                "point_on_light",
                format!("{point_on_light} is not on the sphere light"),
            ));
        }
        // Where rounding swamps the radius the direction from the centre is
        // noise (or zero): such a light is a point, and emits toward the
        // casters as far as one view can see.
        let normal = if d.length() > 16.0 * noise {
            d.normalize()
        } else {
            let (lo, hi) = check_bounds("casters_bounds", casters_bounds)?;
            (0.5 * (lo + hi) - c).normalize_or(DVec3::NEG_Y)
        };
        // Up hint: the world axis least aligned with the view direction is
        // chosen in `fit` once the direction is known.
        fit(
            p,
            normal,
            None,
            DVec3::ZERO,
            casters_bounds,
            receivers_bounds,
            size,
        )
    }
}

/// The casters' and the receivers' bounds, for a light view fitted to
/// both; `None` when nothing casts or nothing receives (then every light
/// is fully visible: [`fully_lit`]).
pub fn map_bounds(scene: &Scene) -> Option<(Bounds, Bounds)> {
    Some((caster_bounds(scene)?, receiver_bounds(scene)?))
}

/// Every light fully visible at every pixel (Vcoef 1): the answer of a
/// light-view technique when [`map_bounds`] is `None`.
pub fn fully_lit(ctx: &ShadowContext) -> ShadowOutput {
    let n = ctx.gbuffer.len();
    ShadowOutput {
        lights: ctx
            .scene
            .lights
            .iter()
            .map(|_| LightTerm::Vcoef(vec![1.0; n]))
            .collect(),
        ..ShadowOutput::default()
    }
}

/// The casters' bounds: every object with `cast_shadows`; `None` if there
/// is none.
pub fn caster_bounds(scene: &Scene) -> Option<Bounds> {
    bounds_of(scene, |o| scene.objects[o].cast_shadows)
}

/// The receivers' bounds: every object with `receive_shadows`.
pub fn receiver_bounds(scene: &Scene) -> Option<Bounds> {
    bounds_of(scene, |o| scene.objects[o].receive_shadows)
}

fn bounds_of(scene: &Scene, keep: impl Fn(usize) -> bool) -> Option<Bounds> {
    let mut it = (0..scene.objects.len())
        .filter(|&o| keep(o))
        .flat_map(|o| scene.objects[o].mesh.positions.iter());
    let first = *it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
}

fn check_size((w, h): (u32, u32)) -> Result<()> {
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE || w as u64 * h as u64 > MAX_DEPTH_TEXELS {
        return Err(Error::param(
            "size",
            format!(
                "{w}×{h} texels: each side must be in 1..={MAX_SIDE} and the total at most \
                 {MAX_DEPTH_TEXELS}"
            ),
        ));
    }
    Ok(())
}

fn check_point(p: Vec3) -> Result<DVec3> {
    if !p.is_finite() {
        return Err(Error::param("point_on_light", format!("{p} is not finite")));
    }
    Ok(p.as_dvec3())
}

fn check_bounds(name: &str, (lo, hi): Bounds) -> Result<(DVec3, DVec3)> {
    if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
        return Err(Error::param(
            name,
            format!("[{lo}, {hi}] is not a finite box with min <= max"),
        ));
    }
    Ok((lo.as_dvec3(), hi.as_dvec3()))
}

/// A half-space `normal · x >= offset`.
#[derive(Clone, Copy)]
struct HalfSpace {
    normal: DVec3,
    offset: f64,
}

/// The vertices of the box `[lo, hi]` cut by the half-spaces: each face
/// clipped in turn (Sutherland–Hodgman). Every vertex of the cut box lies
/// on a face of the box (at most two cutting planes meet in a vertex, the
/// third plane is a face), so the clipped faces' vertices hold them all;
/// empty when nothing is left.
fn cut_box((lo, hi): (DVec3, DVec3), cuts: &[HalfSpace]) -> Vec<DVec3> {
    let corner = |k: usize| {
        DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        )
    };
    // Faces by corner index (cycles; orientation does not matter here).
    const FACES: [[usize; 4]; 6] = [
        [0, 2, 6, 4],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 5, 7, 6],
    ];
    let mut out = Vec::new();
    for face in FACES {
        let mut poly: Vec<DVec3> = face.iter().map(|&k| corner(k)).collect();
        for cut in cuts {
            let side = |q: DVec3| cut.normal.dot(q) - cut.offset;
            let mut next = Vec::with_capacity(poly.len() + 1);
            for (i, &a) in poly.iter().enumerate() {
                let b = poly[(i + 1) % poly.len()];
                let (sa, sb) = (side(a), side(b));
                if sa >= 0.0 {
                    next.push(a);
                }
                if (sa >= 0.0) != (sb >= 0.0) {
                    // sa and sb differ in sign, so sa - sb is not zero and
                    // the parameter lies in [0, 1].
                    let t = sa / (sa - sb);
                    next.push(a + (b - a) * t);
                }
            }
            poly = next;
            if poly.is_empty() {
                break;
            }
        }
        out.extend(poly);
    }
    out
}

/// Tangent window `(left, right, bottom, top)` of points seen from `eye`
/// in the frame `(right, up, forward)`; all points have depth > 0.
fn window_of(points: &[DVec3], eye: DVec3, frame: [DVec3; 3]) -> [f64; 4] {
    let [r, u, f] = frame;
    let mut w = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for &q in points {
        let d = q - eye;
        let z = d.dot(f);
        let (x, y) = (d.dot(r) / z, d.dot(u) / z);
        w = [w[0].min(x), w[1].max(x), w[2].min(y), w[3].max(y)];
    }
    w
}

/// The view from `p` (emitting into `normal · (x - p) > 0`) looking along
/// `forward` (or, when `None`, toward the cut casters' bounds), fitted as
/// the constructors describe.
fn fit(
    p: DVec3,
    normal: DVec3,
    forward: Option<DVec3>,
    up_hint: DVec3,
    casters: Bounds,
    receivers: Bounds,
    size: (u32, u32),
) -> Result<Option<LightView>> {
    let casters = check_bounds("casters_bounds", casters)?;
    let receivers = check_bounds("receivers_bounds", receivers)?;
    let emit = HalfSpace {
        normal,
        offset: normal.dot(p),
    };
    let lit_casters = cut_box(casters, &[emit]);
    let lit_receivers = cut_box(receivers, &[emit]);
    if lit_casters.is_empty() || lit_receivers.is_empty() {
        return Ok(None);
    }
    let forward = match forward {
        Some(f) => f,
        None => {
            let mean: DVec3 = lit_casters
                .iter()
                .map(|&q| (q - p).normalize_or_zero())
                .sum();
            let f = mean.normalize_or_zero();
            if f == DVec3::ZERO {
                normal
            } else {
                f
            }
        }
    };
    let up_hint = if up_hint != DVec3::ZERO {
        up_hint
    } else {
        // The world axis least aligned with `forward`: never parallel.
        let a = forward.abs();
        if a.x <= a.y && a.x <= a.z {
            DVec3::X
        } else if a.y <= a.z {
            DVec3::Y
        } else {
            DVec3::Z
        }
    };
    let reach = lit_casters
        .iter()
        .chain(&lit_receivers)
        .map(|&q| (q - p).length())
        .fold(0.0, f64::max);
    if !(reach > 0.0 && reach.is_finite()) {
        return Ok(None); // the bounds are the point itself
    }
    let z_min = lit_casters
        .iter()
        .map(|&q| (q - p).dot(forward))
        .fold(f64::INFINITY, f64::min);
    let near = (0.5 * z_min).max(MIN_NEAR * reach);
    let near_cut = HalfSpace {
        normal: forward,
        offset: forward.dot(p) + near,
    };
    let seen_casters = cut_box(casters, &[emit, near_cut]);
    let seen_receivers = cut_box(receivers, &[emit, near_cut]);
    if seen_casters.is_empty() || seen_receivers.is_empty() {
        return Ok(None);
    }
    // The view's own frame, so the window is in its coordinates.
    let right = forward.cross(up_hint).normalize_or_zero();
    if right == DVec3::ZERO {
        return Err(Error::param("light", "degenerate view direction"));
    }
    let frame = [right, right.cross(forward), forward];
    let wc = window_of(&seen_casters, p, frame);
    let wr = window_of(&seen_receivers, p, frame);
    let mut w = [
        wc[0].max(wr[0]),
        wc[1].min(wr[1]),
        wc[2].max(wr[2]),
        wc[3].min(wr[3]),
    ];
    if !(w[0] <= w[1] && w[2] <= w[3]) {
        return Ok(None); // no caster inside the receivers' cone
    }
    let inside = w.iter().all(|t| t.abs() <= MAX_TAN);
    let complete = z_min >= near && inside;
    for t in &mut w {
        *t = t.clamp(-MAX_TAN, MAX_TAN);
    }
    let (px, py) = (
        WINDOW_PAD * (w[1] - w[0]) + 1e-9,
        WINDOW_PAD * (w[3] - w[2]) + 1e-9,
    );
    let extent = Extent::Window {
        left: (w[0] - px) * near,
        right: (w[1] + px) * near,
        bottom: (w[2] - py) * near,
        top: (w[3] + py) * near,
    };
    let view = View::from_frustum(p, forward, up_hint, extent, size.0, size.1, near)?;
    Ok(Some(LightView { view, complete }))
}

/// Per-texel depth of some triangles seen from a view.
///
/// Stores the linear depth: the distance along the view's forward axis of
/// the nearest drawn surface through the texel centre, as `f32`, and
/// `f32::INFINITY` where nothing is drawn. Linear rather than reversed Z
/// because a shadow-map test compares it with a receiver's own distance
/// along the light view's axis ([`View::depth_of`]) and filters
/// (averages) depths, both meaningful only for linear depth; `f32` keeps the
/// same relative precision at any distance.
#[derive(Debug, Clone)]
pub struct DepthMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    depth: Vec<f32>,
}

impl DepthMap {
    /// Linear depth of texel `(x, y)` (row 0 at the top).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.depth[(y * self.width + x) as usize]
    }

    /// Every texel's depth, row-major.
    pub fn as_slice(&self) -> &[f32] {
        &self.depth
    }

    /// Bytes the map holds (one `f32` per texel).
    pub fn memory_bytes(&self) -> u64 {
        self.depth.len() as u64 * 4
    }
}

/// The depth of the casters (objects with `cast_shadows`) from `view`.
pub fn caster_depth_map(scene: &Scene, geometry: &SceneGeometry, view: &View) -> Result<DepthMap> {
    let casts: Vec<bool> = scene.objects.iter().map(|o| o.cast_shadows).collect();
    depth_map(
        geometry,
        |t| casts[geometry.triangle_object[t as usize] as usize],
        view,
    )
}

/// Draws the triangles of `geometry` for which `keep(triangle index)` holds
/// from `view`, with the depth-only state of the G-buffer's depth pass
/// (closer wins, no culling: a depth map sees both facings), and returns
/// the linear depth per texel (see [`DepthMap`]). Opacity is not looked
/// at: every kept triangle is a surface. Sizes beyond [`MAX_DEPTH_TEXELS`]
/// are refused before anything is allocated.
pub fn depth_map(
    geometry: &SceneGeometry,
    keep: impl Fn(u32) -> bool + Sync,
    view: &View,
) -> Result<DepthMap> {
    check_size((view.width, view.height))?;
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
    draw(
        &mut fb,
        &mut targets,
        &RasterState::default(),
        &vertices,
        &triangles,
        &NoFragmentStage,
    )?;
    drop((vertices, triangles));
    // Reversed Z is `near / distance`: invert it in f64, one rounding.
    // Each tile's depth is freed once copied, so the peak stays near one
    // map plus one framebuffer band.
    let (w, h) = (view.width as usize, view.height as usize);
    let near = view.near;
    let mut depth = vec![0.0f32; w * h];
    depth
        .par_chunks_mut(w * TILE_SIZE)
        .zip(fb.tiles_mut().par_chunks_mut(grid.tiles_x))
        .for_each(|(band, tiles)| {
            let rows = band.len() / w;
            for (tx, tile) in tiles.iter_mut().enumerate() {
                let x0 = tx * TILE_SIZE;
                let cols = TILE_SIZE.min(w - x0);
                for r in 0..rows {
                    let src = &tile.depth[r * TILE_SIZE..r * TILE_SIZE + cols];
                    let dst = &mut band[r * w + x0..r * w + x0 + cols];
                    for (o, &d) in dst.iter_mut().zip(src) {
                        *o = if d == FAR_DEPTH {
                            f32::INFINITY
                        } else {
                            (near / d as f64) as f32
                        };
                    }
                }
                tile.depth = Box::new([]);
            }
        });
    debug_assert_eq!(depth.len(), w * h);
    Ok(DepthMap {
        width: view.width,
        height: view.height,
        depth,
    })
}
