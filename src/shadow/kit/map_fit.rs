//! A map window fitted object by object.
//!
//! [`light_view_at`] fits the window to the casters' and the receivers'
//! bounding boxes. One box over all casters is loose when they are spread
//! in depth: a small caster next to the light and a ground far away give
//! a box whose corner near the light spans a huge angle (up to the
//! clamp of [`MAX_TAN`]), and the map's texels grow a hundredfold (every
//! stiff case of `tests/it/shadow_map_stiff.rs` but contact: acne or lost
//! shadows everywhere). A receiver's shadow from the map's eye can only
//! come from a caster in front of it, so the window needed is
//!
//! `W = ∪_r ( W(r) ∩ ∪_{c in front of r} W(c) )`
//!
//! over receiver objects `r` and caster objects `c`, with `W(o)` the
//! window of `o`'s own bounding box seen from the eye. "In front" is
//! conservative: the nearest depth of `c`'s box is below the farthest of
//! `r`'s; an object is its own caster unless it is planar (a plane cannot
//! shadow itself). A box with a corner on or behind the near plane gets
//! the whole loose window (never tighter than it is safe to be). The view
//! keeps the loose view's eye, axes and near plane; only its window
//! shrinks, so a receiver or a caster is never cut that the loose view
//! holds and that can matter.

use crate::error::Result;
use crate::scene::{Light, Scene};
use crate::shadow::kit::light_view::{Bounds, LightView, MAX_TAN};
use crate::shadow::kit::shadow_maps::light_view_at;
use crate::view::{Extent, View};
use glam::{DVec3, Vec3};

/// Tangent window `[left, right, bottom, top]`.
type Window = [f64; 4];

/// One object's box as the loose view sees it.
struct Seen {
    window: Window,
    near: f64,
    far: f64,
    casts: bool,
    receives: bool,
    planar: bool,
}

fn is_planar(positions: &[Vec3]) -> bool {
    let Some(&a) = positions.first() else {
        return true;
    };
    let a = a.as_dvec3();
    let extent = positions
        .iter()
        .map(|p| (p.as_dvec3() - a).length())
        .fold(0.0, f64::max);
    // A normal from the vertex farthest from `a` and the one farthest from
    // that line: the best-conditioned pair, not the first triangle.
    let b = positions
        .iter()
        .map(|p| p.as_dvec3())
        .max_by(|p, q| (*p - a).length().total_cmp(&(*q - a).length()))
        .unwrap_or(a);
    let n = positions
        .iter()
        .map(|p| (b - a).cross(p.as_dvec3() - a))
        .max_by(|p, q| p.length().total_cmp(&q.length()))
        .unwrap_or(DVec3::ZERO)
        .normalize_or_zero();
    if n == DVec3::ZERO {
        return true; // all on a line: casts no area
    }
    positions
        .iter()
        .all(|p| n.dot(p.as_dvec3() - a).abs() <= 1e-6 * extent)
}

fn intersect(a: Window, b: Window) -> Option<Window> {
    let w = [
        a[0].max(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].min(b[3]),
    ];
    (w[0] <= w[1] && w[2] <= w[3]).then_some(w)
}

fn union(a: Option<Window>, b: Window) -> Window {
    match a {
        None => b,
        Some(a) => [
            a[0].min(b[0]),
            a[1].max(b[1]),
            a[2].min(b[2]),
            a[3].max(b[3]),
        ],
    }
}

/// The light view from `point` as [`light_view_at`] fits it, its window
/// then shrunk to what receivers can need (see the module); `Ok(None)`
/// when no receiver has a caster in front of it.
pub fn tight_light_view(
    scene: &Scene,
    light: &Light,
    point: Vec3,
    casters: Bounds,
    receivers: Bounds,
    size: (u32, u32),
) -> Result<Option<LightView>> {
    let Some(loose) = light_view_at(light, point, casters, receivers, size)? else {
        return Ok(None);
    };
    let v = &loose.view;
    let full = [v.window.left, v.window.right, v.window.bottom, v.window.top];
    let seen: Vec<Seen> = scene
        .objects
        .iter()
        .filter(|o| !o.mesh.positions.is_empty() && (o.cast_shadows || o.receive_shadows))
        .map(|o| {
            let p = &o.mesh.positions;
            let (lo, hi) = p
                .iter()
                .fold((p[0], p[0]), |(l, h), q| (l.min(*q), h.max(*q)));
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            let mut window = [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ];
            let (mut near, mut far) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut behind = false;
            for k in 0..8 {
                let c = DVec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                let d = c - v.eye;
                let z = d.dot(v.forward);
                near = near.min(z);
                far = far.max(z);
                if !(z >= v.near) {
                    behind = true;
                    continue;
                }
                let (x, y) = (d.dot(v.right) / z, d.dot(v.up) / z);
                window = [
                    window[0].min(x),
                    window[1].max(x),
                    window[2].min(y),
                    window[3].max(y),
                ];
            }
            if behind {
                window = full;
            }
            Seen {
                window,
                near,
                far,
                casts: o.cast_shadows,
                receives: o.receive_shadows,
                planar: is_planar(p),
            }
        })
        .collect();
    let mut needed: Option<Window> = None;
    for (i, r) in seen.iter().enumerate().filter(|(_, r)| r.receives) {
        let mut shadowing: Option<Window> = None;
        for (j, c) in seen.iter().enumerate() {
            if c.casts && c.near < r.far && (i != j || !r.planar) {
                shadowing = Some(union(shadowing, c.window));
            }
        }
        if let Some(w) = shadowing.and_then(|s| intersect(s, r.window)) {
            needed = Some(union(needed, w));
        }
    }
    let Some(w) = needed.and_then(|w| intersect(w, full)) else {
        return Ok(None);
    };
    let w = w.map(|t| t.clamp(-MAX_TAN, MAX_TAN));
    // The same relative padding as the loose fit, so the boxes' boundary
    // stays inside in spite of rounding.
    let (px, py) = (1e-6 * (w[1] - w[0]) + 1e-9, 1e-6 * (w[3] - w[2]) + 1e-9);
    let near = v.near;
    let extent = Extent::Window {
        left: (w[0] - px) * near,
        right: (w[1] + px) * near,
        bottom: (w[2] - py) * near,
        top: (w[3] + py) * near,
    };
    let view = View::from_frustum(v.eye, v.forward, v.up, extent, size.0, size.1, near)?;
    Ok(Some(LightView {
        view,
        complete: loose.complete,
    }))
}
