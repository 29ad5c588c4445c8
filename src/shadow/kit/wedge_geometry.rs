//! Penumbra wedges as closed convex polyhedra with vertices at infinity,
//! split in an outer and an inner half by the edge's shadow-volume quad.
//!
//! The thesis (appendix 3.B) builds a wedge from the edge moved to equal
//! distance from the light centre and four points around the centre, which
//! suits a vertex program. We build each bounding plane directly and
//! exactly for the light's real shape, in f64:
//!
//! - **front / back**: the two planes through the edge's line that touch
//!   the light (for a rect light the extreme corners around the line, for a
//!   sphere the tangent planes), so every shadow ray of the edge lies
//!   between them;
//! - **sides**: at each end `q`, the plane through `q` containing the
//!   central plane's normal that touches the light, with the light on its
//!   outer side: every shadow ray through `q` and through the rest of the
//!   edge lies inside;
//! - **central plane** (through the edge and the light centre): the
//!   shadow-volume quad of the edge lies in it and splits the wedge.
//!
//! The split face contains the quad *as the very same two triangles the
//! shadow-volume pass drew* (same clip-space vertices, same order), plus
//! the two cones beside it. Membership of a receiver in the inner or the
//! outer half is decided by the rasterizer on that shared face, exactly as
//! the stencil count was: the sign the wedge adds with and the count it
//! corrects can never disagree, even for a receiver exactly on the quad.
//! All other faces bound regions where the edge's contribution vanishes, so
//! their ties do not matter. Faces share vertices exactly (no T-junctions),
//! including at infinity, so z-fail counting of each half is exact.

use super::light_frame::RectFrame;
use crate::raster::ClipVertex;
use crate::view::View;
use glam::{DVec3, Vec3};

/// The light a wedge is built around.
#[derive(Debug, Clone, Copy)]
pub enum LightBound {
    /// A parallelogram light.
    Rect(RectFrame),
    /// A sphere light.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
}

impl LightBound {
    /// The centre (hard shadows are cast from it).
    pub fn center(&self) -> DVec3 {
        match self {
            LightBound::Rect(f) => f.center,
            LightBound::Sphere { center, .. } => *center,
        }
    }

    /// The range of angles the light spans around the line through `o`
    /// with unit direction `ex`, measured from `k` (unit, ⟂ `ex`, towards
    /// the centre) towards `n = ex × k`... `None` when the light meets the
    /// line or spans half a turn or more around it.
    fn angle_range(&self, o: DVec3, ex: DVec3, k: DVec3, n: DVec3) -> Option<(f64, f64)> {
        let angle = |x: DVec3| {
            let y = x - o;
            let y = y - ex * y.dot(ex);
            (y.length() > 0.0).then(|| y.dot(n).atan2(y.dot(k)))
        };
        let (lo, hi) = match self {
            LightBound::Rect(f) => {
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for c in f.corners() {
                    let a = angle(c)?;
                    lo = lo.min(a);
                    hi = hi.max(a);
                }
                (lo, hi)
            }
            LightBound::Sphere { center, radius } => {
                let y = *center - o;
                let d = (y - ex * y.dot(ex)).length();
                if d <= *radius {
                    return None;
                }
                let half = (radius / d).asin();
                (-half, half)
            }
        };
        // The centre is at angle 0; a light reaching ±π/2 from it is so
        // close to the line that the wedge would not be convex.
        (lo > -std::f64::consts::FRAC_PI_2
            && hi < std::f64::consts::FRAC_PI_2
            && lo <= 0.0
            && hi >= 0.0)
            .then_some((lo, hi))
    }

    /// Whether the whole light is on the non-positive side of the plane
    /// through `q` with normal `m` (`m` ⟂ the central plane's normal).
    fn behind(&self, q: DVec3, m: DVec3) -> bool {
        match self {
            LightBound::Rect(f) => {
                let scale = f.u.length() + f.v.length() + (f.center - q).length();
                f.corners().iter().all(|c| m.dot(*c - q) <= 1e-12 * scale)
            }
            LightBound::Sphere { center, radius } => m.dot(*center - q) <= -radius * (1.0 - 1e-12),
        }
    }

    /// In the central plane (basis `ex`, `k` at `q`), the extreme angles
    /// of the light's projection as seen from `q`, or `None` when `q` is
    /// inside it.
    fn in_plane_angles(&self, q: DVec3, ex: DVec3, k: DVec3) -> Option<(f64, f64, f64)> {
        let to2 = |x: DVec3| {
            let y = x - q;
            (y.dot(ex), y.dot(k))
        };
        let (cx, ck) = to2(self.center());
        let base = ck.atan2(cx);
        let rel = |a: f64| {
            let mut d = a - base;
            while d > std::f64::consts::PI {
                d -= std::f64::consts::TAU;
            }
            while d < -std::f64::consts::PI {
                d += std::f64::consts::TAU;
            }
            d
        };
        let (lo, hi) = match self {
            LightBound::Rect(f) => {
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for c in f.corners() {
                    let (x, y) = to2(c);
                    if x == 0.0 && y == 0.0 {
                        return None;
                    }
                    let d = rel(y.atan2(x));
                    lo = lo.min(d);
                    hi = hi.max(d);
                }
                (lo, hi)
            }
            LightBound::Sphere { radius, .. } => {
                let d = (cx * cx + ck * ck).sqrt();
                if d <= *radius {
                    return None;
                }
                let half = (radius / d).asin();
                (-half, half)
            }
        };
        (hi - lo < std::f64::consts::PI * 0.999).then_some((base, lo, hi))
    }
}

/// One half of a penumbra wedge.
#[derive(Debug, Clone, Copy)]
pub struct HalfWedge {
    /// The silhouette edge in shadow-volume quad order.
    pub q0: DVec3,
    /// Second endpoint.
    pub q1: DVec3,
    /// The edge's multiplicity (copies of its quad in the volume).
    pub weight: u32,
    /// Outside the shadow-volume quad (adds occlusion) or inside (removes).
    pub outer: bool,
}

/// Per rasterized triangle: its half-wedge and the sign its facing counts
/// with.
#[derive(Debug, Clone, Copy)]
pub struct WedgePrimitive {
    /// Index into [`WedgeSet::halves`].
    pub half: u32,
    /// −1 when the triangle is wound inward for its half (the shared
    /// shadow-volume quad of the outer half).
    pub flip: i8,
}

/// Every half-wedge of one light, ready to draw.
#[derive(Debug, Clone, Default)]
pub struct WedgeSet {
    /// Clip-space vertices.
    pub vertices: Vec<ClipVertex<0>>,
    /// Triangles, grouped by half-wedge (a half's triangles are
    /// contiguous, in half order).
    pub triangles: Vec<[u32; 3]>,
    /// One entry per triangle.
    pub primitives: Vec<WedgePrimitive>,
    /// The halves.
    pub halves: Vec<HalfWedge>,
}

/// A silhouette edge as the shadow-volume pass drew it: quad
/// `[q0, q1, q1 at infinity, q0 at infinity]`, `weight` copies.
#[derive(Debug, Clone, Copy)]
pub struct SilhouetteQuad {
    /// First finite corner.
    pub q0: Vec3,
    /// Second finite corner.
    pub q1: Vec3,
    /// Copies drawn (|multiplicity|).
    pub weight: u32,
}

/// Outward normal of the plane through homogeneous points, as `(n, d)` with
/// `n·x + d·w = 0` on the plane: `n = Σ w_i (x_j × x_k)` cyclically.
fn homogeneous_normal(p: [(DVec3, f64); 3]) -> DVec3 {
    let [(a, wa), (b, wb), (c, wc)] = p;
    b.cross(c) * wa + c.cross(a) * wb + a.cross(b) * wc
}

impl WedgeSet {
    fn vertex(&mut self, clip: glam::Vec4) -> u32 {
        self.vertices.push(ClipVertex {
            position: clip,
            varyings: [],
        });
        (self.vertices.len() - 1) as u32
    }
}

/// Every half-wedge of one light: halves that may hold the eye (or touch
/// the near plane) are counted z-fail, the others z-pass.
#[derive(Debug, Clone, Default)]
pub struct Wedges {
    /// Counted with the faces behind each receiver.
    pub zfail: WedgeSet,
    /// Counted with the faces in front of each receiver.
    pub zpass: WedgeSet,
    /// Silhouette edges without a wedge: zero length, or so close to the
    /// light that no convex wedge bounds their penumbra.
    pub skipped: usize,
}

impl Wedges {
    /// Adds the two halves of the wedge of `quad` (only the outer or the
    /// inner one with `only = Some(outer)`); returns false (and adds
    /// nothing) when the edge has no bounded wedge.
    pub fn add(
        &mut self,
        view: &View,
        light: &LightBound,
        light_point: Vec3,
        quad: SilhouetteQuad,
        only: Option<bool>,
    ) -> bool {
        let near_margin = near_margin(view);
        let Some(edge) = EdgeFrame::new(light, &quad) else {
            return false;
        };
        let (Some(side0), Some(side1)) = (
            edge.side_plane(light, edge.q0, -1.0),
            edge.side_plane(light, edge.q1, 1.0),
        ) else {
            return false;
        };
        // The shadow-volume quad's vertices exactly as that pass made them.
        let volume_quad = [
            view.clip_point(quad.q0),
            view.clip_point(quad.q1),
            view.clip_direction(quad.q1 - light_point),
            view.clip_direction(quad.q0 - light_point),
        ];
        // The quad's corners at infinity (directions from the light point).
        let far0 = (quad.q0 - light_point).as_dvec3();
        let far1 = (quad.q1 - light_point).as_dvec3();
        // Outward normal of the quad for the volume (inner half's outside).
        let n_out = homogeneous_normal([(edge.q0, 1.0), (edge.q1, 1.0), (far1, 0.0)]);
        if n_out.length_squared() == 0.0 {
            return false;
        }
        for outer in [false, true] {
            if only.is_some_and(|wanted| wanted != outer) {
                continue;
            }
            let Some(rays) = HalfRays::new(&edge, n_out, outer, [side0, side1]) else {
                return false;
            };
            // Inside-test of the eye with a margin covering the near
            // rectangle: when some plane has the eye clearly outside, no
            // face is cut by the near plane and z-pass counting is exact
            // (and never needs the faces behind the receivers).
            let central_normal = if outer { n_out } else { -n_out }.normalize();
            let eye = view.eye;
            let eye_outside = [
                central_normal.dot(eye - edge.q0),
                rays.bound_normal.dot(eye - edge.q0),
                side0.dot(eye - edge.q0),
                side1.dot(eye - edge.q1),
            ]
            .iter()
            .any(|&distance| distance < -near_margin);
            let set = if eye_outside {
                &mut self.zpass
            } else {
                &mut self.zfail
            };
            let half = HalfWedge {
                q0: edge.q0,
                q1: edge.q1,
                weight: quad.weight,
                outer,
            };
            set.push_half(view, half, volume_quad, [far0, far1], &rays, eye_outside);
        }
        true
    }
}

/// The radius of a ball around the eye holding the near rectangle, with
/// slack.
#[inline]
fn near_margin(view: &View) -> f64 {
    let aspect = view.width as f64 / view.height as f64;
    let tan_half_fov = view.tan_half_fov;
    2.0 * view.near * (1.0 + tan_half_fov * tan_half_fov * (1.0 + aspect * aspect)).sqrt()
}

/// A silhouette edge in f64 with its frame around the light's centre.
struct EdgeFrame {
    q0: DVec3,
    q1: DVec3,
    /// `q1 − q0`.
    along: DVec3,
    /// Unit edge direction.
    ex: DVec3,
    /// Unit, ⟂ `ex`, from the edge's line towards the light's centre.
    k: DVec3,
    /// `ex × k`: the central plane's normal.
    n: DVec3,
    /// The angles the light spans around the edge's line, from `k`
    /// towards `n`.
    phi_lo: f64,
    /// Upper end.
    phi_hi: f64,
}

impl EdgeFrame {
    /// `None` for an edge without a bounded wedge: zero length or weight,
    /// through the light's centre, or too close to the light.
    #[inline]
    fn new(light: &LightBound, quad: &SilhouetteQuad) -> Option<EdgeFrame> {
        let (q0, q1) = (quad.q0.as_dvec3(), quad.q1.as_dvec3());
        let centre = light.center();
        let along = q1 - q0;
        if along.length_squared() == 0.0 || quad.weight == 0 {
            return None;
        }
        let ex = along.normalize();
        let foot = q0 + ex * (centre - q0).dot(ex);
        let to_light = centre - foot;
        if to_light.length_squared() == 0.0 {
            return None;
        }
        let k = to_light.normalize();
        let n = ex.cross(k);
        let (phi_lo, phi_hi) = light.angle_range(q0, ex, k, n)?;
        Some(EdgeFrame {
            q0,
            q1,
            along,
            ex,
            k,
            n,
            phi_lo,
            phi_hi,
        })
    }

    /// The side plane's inward normal at end `q` (`outward`: −1 at `q0`,
    /// +1 at `q1`): the tangent through `q` (containing `n`) whose shadow
    /// ray is the most outward along the edge.
    #[inline]
    fn side_plane(&self, light: &LightBound, q: DVec3, outward: f64) -> Option<DVec3> {
        let (ex, k, n) = (self.ex, self.k, self.n);
        let (base, lo, hi) = light.in_plane_angles(q, ex, k)?;
        // Shadow rays through q run at angles (light angle + π); pick
        // the light angle whose continuation leans furthest outward.
        let candidates = [base + lo, base + hi];
        let lean = |angle: f64| -(angle.cos()) * outward;
        let angle = if lean(candidates[0]) >= lean(candidates[1]) {
            candidates[0]
        } else {
            candidates[1]
        };
        let shadow_ray = -(ex * angle.cos() + k * angle.sin());
        let normal = n.cross(shadow_ray).normalize();
        // Inside is towards the other end of the edge.
        let normal = if normal.dot(ex) * outward < 0.0 {
            normal
        } else {
            -normal
        };
        // The light must be wholly outside: otherwise some shadow ray
        // through q leans further out than the chosen one.
        (normal.dot(ex).abs() > 1e-9 && light.behind(q, normal)).then_some(normal)
    }
}

/// One half's bounding (front or back) plane and its edges at infinity.
struct HalfRays {
    /// Inward normal of the bounding plane.
    bound_normal: DVec3,
    /// Where the central plane meets the side planes at `q0` and `q1`
    /// (the cones beside the quad).
    cone: [DVec3; 2],
    /// Where the bounding plane meets the side planes at `q0` and `q1`.
    bound: [DVec3; 2],
    /// A point inside the half, for orienting its faces outward.
    interior: DVec3,
}

impl HalfRays {
    /// `None` when a ray is degenerate (zero or not finite).
    #[inline]
    fn new(edge: &EdgeFrame, n_out: DVec3, outer: bool, sides: [DVec3; 2]) -> Option<HalfRays> {
        let (ex, k, n) = (edge.ex, edge.k, edge.n);
        let [side0, side1] = sides;
        // The bounding plane of this half: angle ψ = π + φ.
        let phi = if (n_out.dot(n) > 0.0) == outer {
            edge.phi_lo
        } else {
            edge.phi_hi
        };
        let bound_dir = -(k * phi.cos() + n * phi.sin());
        let bound_normal = {
            let normal = ex.cross(bound_dir).normalize();
            // Inside contains the quad's half-plane (direction −k).
            if normal.dot(-k) >= 0.0 {
                normal
            } else {
                -normal
            }
        };
        let ray = |a: DVec3, b: DVec3, into: DVec3| {
            let direction = a.cross(b);
            if direction.dot(into) >= 0.0 {
                direction
            } else {
                -direction
            }
        };
        let cone0 = ray(n, side0, -k);
        let cone1 = ray(n, side1, -k);
        let bound0 = ray(bound_normal, side0, bound_dir);
        let bound1 = ray(bound_normal, side1, bound_dir);
        if [cone0, cone1, bound0, bound1]
            .iter()
            .any(|direction| !(direction.length_squared() > 0.0) || !direction.is_finite())
        {
            return None;
        }
        let mid = (edge.q0 + edge.q1) * 0.5;
        let spread =
            cone0.normalize() + cone1.normalize() + bound0.normalize() + bound1.normalize();
        let interior = mid + spread * (0.05 * edge.along.length());
        Some(HalfRays {
            bound_normal,
            cone: [cone0, cone1],
            bound: [bound0, bound1],
            interior,
        })
    }
}

impl WedgeSet {
    /// Adds one half-wedge: its vertices, the shared quad (`volume_quad`,
    /// as the volume pass drew it, with corners at infinity `far`) and
    /// its faces, the cap at infinity only when counted z-fail.
    #[inline]
    fn push_half(
        &mut self,
        view: &View,
        half_wedge: HalfWedge,
        volume_quad: [glam::Vec4; 4],
        far: [DVec3; 2],
        rays: &HalfRays,
        eye_outside: bool,
    ) {
        let (q0, q1) = (half_wedge.q0, half_wedge.q1);
        let [far0, far1] = far;
        let [cone0, cone1] = rays.cone;
        let [bound0, bound1] = rays.bound;
        let interior = rays.interior;
        let outer = half_wedge.outer;
        let set = self;
        let half = set.halves.len() as u32;
        set.halves.push(half_wedge);
        let iq0 = set.vertex(volume_quad[0]);
        let iq1 = set.vertex(volume_quad[1]);
        let ifar1 = set.vertex(volume_quad[2]);
        let ifar0 = set.vertex(volume_quad[3]);
        let dir = |set: &mut WedgeSet, d: DVec3| set.vertex(view.clip_direction(d.as_vec3()));
        let icone0 = dir(set, cone0);
        let icone1 = dir(set, cone1);
        let ibound0 = dir(set, bound0);
        let ibound1 = dir(set, bound1);
        // The shared quad, as drawn by the volume pass.
        let flip = if outer { -1 } else { 1 };
        for triangle in [[iq0, iq1, ifar1], [iq0, ifar1, ifar0]] {
            set.triangles.push(triangle);
            set.primitives.push(WedgePrimitive { half, flip });
        }
        // World-space (homogeneous) position of each vertex index, for
        // orientation.
        let world = |i: u32| -> (DVec3, f64) {
            match i {
                _ if i == iq0 => (q0, 1.0),
                _ if i == iq1 => (q1, 1.0),
                _ if i == ifar0 => (far0, 0.0),
                _ if i == ifar1 => (far1, 0.0),
                _ if i == icone0 => (cone0, 0.0),
                _ if i == icone1 => (cone1, 0.0),
                _ if i == ibound0 => (bound0, 0.0),
                _ => (bound1, 0.0),
            }
        };
        let face = |set: &mut WedgeSet, [a, b, c]: [u32; 3]| {
            let p = [world(a), world(b), world(c)];
            let outward = match p.iter().find(|(_, w)| *w == 1.0) {
                Some((finite, _)) => homogeneous_normal(p).dot(interior - *finite) < 0.0,
                // At infinity: outward when the directions turn
                // positively (the volume pass's back caps agree).
                None => p[0].0.dot(p[1].0.cross(p[2].0)) > 0.0,
            };
            set.triangles
                .push(if outward { [a, b, c] } else { [a, c, b] });
            set.primitives.push(WedgePrimitive { half, flip: 1 });
        };
        // The rest of the central face: the cones beside the quad.
        face(set, [iq0, ifar0, icone0]);
        face(set, [iq1, icone1, ifar1]);
        // The bounding (front or back) face.
        face(set, [iq0, iq1, ibound1]);
        face(set, [iq0, ibound1, ibound0]);
        // The sides.
        face(set, [iq0, ibound0, icone0]);
        face(set, [iq1, icone1, ibound1]);
        // The cap at infinity, fanned from bound0 through every direction
        // its edges share with the other faces. Never in front of a
        // receiver, so z-pass halves leave it out.
        if !eye_outside {
            face(set, [ibound0, icone0, ifar0]);
            face(set, [ibound0, ifar0, ifar1]);
            face(set, [ibound0, ifar1, icone1]);
            face(set, [ibound0, icone1, ibound1]);
        }
    }
}
