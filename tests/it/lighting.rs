//! Unshadowed direct lighting against closed forms and brute-force
//! quadrature, the Monte-Carlo estimator against the deterministic
//! integrator, and NaN-freedom in degenerate configurations.
//!
//! References here are written independently of `src/shade` (own BRDF,
//! own quadrature), in `f64`, from the `f32` inputs the renderer sees.

use glam::{DVec3, Vec2, Vec3};
use penumbra::internal::scene::{Light, LightShape, Texture, TextureData};
use penumbra::internal::shade::{
    brdf, direct_from_samples, unshadowed_direct, LightSample, PreparedLight, SurfacePoint,
};
use std::f64::consts::PI;

// ---------------------------------------------------------------- set-up

fn rect(center: Vec3, u: Vec3, v: Vec3, two_sided: bool, radiance: Vec3) -> Light {
    Light {
        shape: LightShape::Rect {
            center,
            u,
            v,
            two_sided,
        },
        radiance,
        texture: None,
    }
}

fn sphere(center: Vec3, radius: f32, radiance: Vec3) -> Light {
    Light {
        shape: LightShape::Sphere { center, radius },
        radiance,
        texture: None,
    }
}

/// A white Lambertian receiver (albedo 1): its radiance from a light of
/// `Le = 1` is the point-to-area form factor `F`.
fn lambert(p: Vec3, n: Vec3) -> SurfacePoint {
    let n = n.normalize();
    SurfacePoint {
        p,
        n,
        ng: n,
        wo: n,
        albedo: Vec3::ONE,
        specular: Vec3::ZERO,
        shininess: 0.0,
    }
}

fn glossy(p: Vec3, n: Vec3, wo: Vec3, albedo: f32, ks: f32, ns: f32) -> SurfacePoint {
    let n = n.normalize();
    SurfacePoint {
        p,
        n,
        ng: n,
        wo: wo.normalize(),
        albedo: Vec3::splat(albedo),
        specular: Vec3::splat(ks),
        shininess: ns,
    }
}

fn d(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

fn rel_err(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}

/// The contract's BRDF, written out independently in f64.
fn ref_brdf(sp: &SurfacePoint, wi: DVec3) -> DVec3 {
    let mut f = d(sp.albedo) / PI;
    if sp.specular != Vec3::ZERO {
        let h = (wi + d(sp.wo)).normalize();
        let ns = f64::from(sp.shininess);
        f += d(sp.specular) * ((ns + 8.0) / (8.0 * PI)) * d(sp.n).dot(h).max(0.0).powf(ns);
    }
    f
}

/// Nearest texel radiance factor at light coordinates (s, t).
fn ref_texel(t: &Texture, s: f64, tt: f64) -> DVec3 {
    let c = ((s * t.width as f64) as usize).min(t.width as usize - 1);
    let r = ((tt * t.height as f64) as usize).min(t.height as usize - 1);
    match &t.data {
        TextureData::Rgb(v) => d(v[r * t.width as usize + c]),
        TextureData::Scalar(v) => DVec3::splat(f64::from(v[r * t.width as usize + c])),
    }
}

/// Brute-force midpoint rule over an `nx × ny` grid on the rect light of
/// `∫ Le f_r cos_p cos_x / r² dA`.
fn quad_rect(
    light: &Light,
    tex: Option<&Texture>,
    sp: &SurfacePoint,
    nx: usize,
    ny: usize,
) -> DVec3 {
    let LightShape::Rect {
        center,
        u,
        v,
        two_sided,
    } = light.shape
    else {
        unreachable!()
    };
    let (c, u, v) = (d(center), d(u), d(v));
    let nl = u.cross(v).normalize();
    let da = 4.0 * u.cross(v).length() / (nx * ny) as f64;
    let (p, n) = (d(sp.p), d(sp.n));
    let mut sum = DVec3::ZERO;
    for j in 0..ny {
        let t = (j as f64 + 0.5) / ny as f64;
        let mut row = DVec3::ZERO;
        for i in 0..nx {
            let s = (i as f64 + 0.5) / nx as f64;
            let x = c + u * (2.0 * s - 1.0) + v * (1.0 - 2.0 * t);
            let dv = x - p;
            let r2 = dv.length_squared();
            let w = dv / r2.sqrt();
            let cos_p = n.dot(w).max(0.0);
            let cx = -nl.dot(w);
            let cos_x = if two_sided { cx.abs() } else { cx.max(0.0) };
            if cos_p == 0.0 || cos_x == 0.0 {
                continue;
            }
            let le = match tex {
                Some(tx) => d(light.radiance) * ref_texel(tx, s, t),
                None => d(light.radiance),
            };
            row += le * ref_brdf(sp, w) * (cos_p * cos_x / r2);
        }
        sum += row;
    }
    sum * da
}

/// Brute-force midpoint rule over the cone a sphere light subtends, in
/// (cos, azimuth) cells of equal solid angle: `∫ Le f_r max(0, n·w) dω`.
fn quad_sphere(light: &Light, sp: &SurfacePoint, n_rings: usize, n_sectors: usize) -> DVec3 {
    let LightShape::Sphere { center, radius } = light.shape else {
        unreachable!()
    };
    let rel = d(center) - d(sp.p);
    let dist = rel.length();
    let axis = rel / dist;
    let sin_a = f64::from(radius) / dist;
    let one_minus_cos = 1.0 - (1.0 - sin_a * sin_a).sqrt();
    let helper = if axis.x.abs() < 0.9 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let t1 = axis.cross(helper).normalize();
    let t2 = axis.cross(t1);
    let d_omega = 2.0 * PI * one_minus_cos / (n_rings * n_sectors) as f64;
    let n = d(sp.n);
    let mut sum = DVec3::ZERO;
    for k in 0..n_rings {
        let q = (k as f64 + 0.5) / n_rings as f64 * one_minus_cos;
        let (cz, sz) = (1.0 - q, (q * (2.0 - q)).sqrt());
        let mut ring = DVec3::ZERO;
        for m in 0..n_sectors {
            let phi = 2.0 * PI * (m as f64 + 0.5) / n_sectors as f64;
            let w = axis * cz + (t1 * phi.cos() + t2 * phi.sin()) * sz;
            let cos_p = n.dot(w);
            if cos_p > 0.0 {
                ring += ref_brdf(sp, w) * cos_p;
            }
        }
        sum += ring;
    }
    sum * d(light.radiance) * d_omega
}

// ------------------------------------------------ analytic form factors

/// Form factor from a differential area to the rectangle `[0, x] × [0, y]`
/// in a parallel plane at distance `c`, one corner above the element
/// (the classic closed form; odd in `x` and in `y`, so signed extents
/// superpose).
fn ff_parallel_corner(x: f64, y: f64, c: f64) -> f64 {
    let (a, b) = (x / c, y / c);
    let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
    (a / sa * (b / sa).atan() + b / sb * (a / sb).atan()) / (2.0 * PI)
}

/// Parallel rect `[x0, x1] × [z0, z1]` (offsets from the element's foot).
fn ff_parallel(x0: f64, x1: f64, z0: f64, z1: f64, c: f64) -> f64 {
    ff_parallel_corner(x1, z1, c) - ff_parallel_corner(x0, z1, c) - ff_parallel_corner(x1, z0, c)
        + ff_parallel_corner(x0, z0, c)
}

/// Form factor from a differential area to the rectangle spanning `[0, b]`
/// along the intersection line and `[0, h]` above the element's plane, in
/// a perpendicular plane at distance `c`:
/// `(1/2π) [atan(b/c) − c/√(c²+h²) · atan(b/√(c²+h²))]`.
fn ff_perp_corner(b: f64, h: f64, c: f64) -> f64 {
    let s = (c * c + h * h).sqrt();
    ((b / c).atan() - c / s * (b / s).atan()) / (2.0 * PI)
}

/// Perpendicular rect `[b0, b1]` along the line × `[h0, h1]` in height;
/// the part below the element's horizon (`h < 0`) contributes nothing.
fn ff_perp(b0: f64, b1: f64, h0: f64, h1: f64, c: f64) -> f64 {
    let (h0, h1) = (h0.max(0.0), h1.max(0.0));
    let f = |b: f64| ff_perp_corner(b, h1, c) - ff_perp_corner(b, h0, c);
    f(b1) - f(b0)
}

// ------------------------------------------------------------ the tests

#[test]
fn brdf_matches_the_contract_formula() {
    let sp = glossy(
        Vec3::ZERO,
        Vec3::Y,
        Vec3::new(0.3, 1.0, 0.2),
        0.6,
        0.4,
        37.0,
    );
    for wi in [
        Vec3::Y,
        Vec3::new(-0.3, 1.0, -0.1),
        Vec3::new(1.0, 0.2, 0.0),
        Vec3::new(0.0, -1.0, 0.3),
    ] {
        let wi = wi.normalize();
        let got = d(brdf(&sp, wi));
        let want = ref_brdf(&sp, d(wi));
        assert!(
            (got - want).abs().max_element() <= 1e-6 * want.max_element(),
            "{got} {want}"
        );
    }
    // Ks = 0: exactly albedo / π whatever the directions.
    let sp = lambert(Vec3::ZERO, Vec3::Y);
    assert_eq!(brdf(&sp, -Vec3::Y), Vec3::splat((1.0 / PI) as f32));
}

#[test]
fn parallel_rect_matches_the_analytic_form_factor() {
    // Light at height 2 facing down (u × v = −Y), half-edges 1.5 × 0.75.
    let (a, b, h) = (1.5f32, 0.75f32, 2.0f32);
    let center = Vec3::new(0.4, h, -0.3);
    let light = rect(center, Vec3::X * a, Vec3::Z * b, false, Vec3::ONE);
    let mut worst = 0.0f64;
    for p in [
        Vec3::new(0.4, 0.0, -0.3),        // centred
        Vec3::new(0.4 - 1.5, 0.0, -1.05), // under a corner
        Vec3::new(2.7, 0.5, 1.9),         // outside the footprint, closer
        Vec3::new(-3.0, 1.99, 0.0),       // nearly in the light's plane
        Vec3::new(0.1, 1.9, 0.2),         // close under the light
        Vec3::new(10.0, -30.0, 7.0),      // far away
    ] {
        let got = f64::from(unshadowed_direct(&light, &[], &lambert(p, Vec3::Y)).x);
        let (pc, c) = (d(center) - d(p), f64::from(h) - f64::from(p.y));
        let want = ff_parallel(
            pc.x - f64::from(a),
            pc.x + f64::from(a),
            pc.z - f64::from(b),
            pc.z + f64::from(b),
            c,
        );
        let e = rel_err(got, want);
        worst = worst.max(e);
        assert!(e < 1e-6, "p = {p}: {got} vs {want} (rel {e:e})");
    }
    println!("parallel rect: worst relative error {worst:e}");
}

#[test]
fn perpendicular_rect_matches_the_analytic_form_factor_with_horizon_clipping() {
    // Light in the plane x = 3 facing −X (u = Z, v = Y: Z × Y = −X),
    // receiver normal +Y: the receiver's horizon is y = p.y.
    let center = Vec3::new(3.0, 1.0, 0.5);
    let (a, b) = (1.25f32, 1.5f32);
    let light = rect(center, Vec3::Z * a, Vec3::Y * b, false, Vec3::ONE);
    let mut worst = 0.0f64;
    for p in [
        Vec3::new(0.0, -0.5, 0.5), // light entirely above the horizon
        Vec3::new(0.0, 1.0, 0.5),  // horizon through the light's middle
        Vec3::new(1.0, 2.0, -1.0), // most of the light below the horizon
        Vec3::new(2.9, 0.0, 0.0),  // very close to the light's plane
    ] {
        let got = f64::from(unshadowed_direct(&light, &[], &lambert(p, Vec3::Y)).x);
        let pc = d(center) - d(p);
        let want = ff_perp(
            pc.z - f64::from(a),
            pc.z + f64::from(a),
            pc.y - f64::from(b),
            pc.y + f64::from(b),
            pc.x,
        );
        let e = rel_err(got, want);
        worst = worst.max(e);
        assert!(e < 1e-6, "p = {p}: {got} vs {want} (rel {e:e})");
    }
    // Entirely below the horizon: nothing.
    let below = unshadowed_direct(&light, &[], &lambert(Vec3::new(0.0, 3.0, 0.0), Vec3::Y));
    assert_eq!(below, Vec3::ZERO);
    println!("perpendicular rect: worst relative error {worst:e}");
}

#[test]
fn one_sided_and_two_sided_rects() {
    let (c, u, v) = (Vec3::new(0.0, 2.0, 0.0), Vec3::X, Vec3::Z * 0.5);
    let one = rect(c, u, v, false, Vec3::splat(3.0));
    let two = rect(c, u, v, true, Vec3::splat(3.0));
    // Emitting side is −Y (X × Z = −Y): below the light.
    let front = lambert(Vec3::new(0.3, 0.5, 0.2), Vec3::new(0.1, 1.0, 0.0));
    let back = lambert(Vec3::new(0.3, 3.5, 0.2), Vec3::new(0.1, -1.0, 0.0)); // mirror image
    let lit = unshadowed_direct(&one, &[], &front);
    assert!(lit.x > 0.0);
    assert_eq!(unshadowed_direct(&one, &[], &back), Vec3::ZERO);
    let mirrored = unshadowed_direct(&two, &[], &back);
    assert!(
        (mirrored - lit).abs().max_element() <= 1e-6 * lit.x,
        "{mirrored} vs {lit}"
    );
    assert_eq!(unshadowed_direct(&two, &[], &front), lit);
}

#[test]
fn tilted_receiver_cutting_the_rect_matches_dense_quadrature() {
    let light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(1.0, 0.0, 0.3),
        Vec3::new(0.0, 0.2, 0.8),
        false,
        Vec3::new(1.0, 2.0, 0.5),
    );
    // Normals tilted so that the tangent plane through p cuts the light.
    let mut worst = 0.0f64;
    for (p, n) in [
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.8, 0.0)),
        (Vec3::new(0.5, 1.0, -0.4), Vec3::new(-0.3, 0.2, 1.0)),
        (Vec3::new(-1.5, 1.5, 0.0), Vec3::new(1.0, -0.2, 0.1)),
    ] {
        let sp = lambert(p, n);
        let got = d(unshadowed_direct(&light, &[], &sp));
        let want = quad_rect(&light, None, &sp, 2000, 2000);
        for k in 0..3 {
            let e = rel_err(got[k], want[k]);
            worst = worst.max(e);
            assert!(e < 1e-5, "p = {p}, n = {n}: {got} vs {want} (rel {e:e})");
        }
    }
    println!("horizon-clipped rect: worst relative error {worst:e} (vs 2000² quadrature)");
}

#[test]
fn sphere_above_the_horizon_matches_the_closed_form() {
    let (c, r) = (Vec3::new(1.0, 4.0, -0.5), 0.8f32);
    let light = sphere(c, r, Vec3::splat(2.0));
    let mut worst = 0.0f64;
    for (p, n) in [
        (Vec3::ZERO, Vec3::Y),
        (Vec3::new(0.5, 2.0, 0.0), Vec3::new(0.3, 1.0, -0.2)),
        (Vec3::new(1.0, 3.0, -0.5), Vec3::Y), // close: α ≈ 53°
        (Vec3::new(-20.0, 0.0, 10.0), Vec3::new(0.5, 1.0, -0.2)),
    ] {
        let sp = lambert(p, n);
        let got = f64::from(unshadowed_direct(&light, &[], &sp).x);
        let rel = d(c) - d(p);
        let sin2a = (f64::from(r) / rel.length()).powi(2);
        let cos_t = d(sp.n).dot(rel.normalize());
        assert!(
            cos_t * cos_t > sin2a,
            "test set-up: cone must be above the horizon"
        );
        // L = albedo/π · π Le sin²α cos θ.
        let want = 2.0 * sin2a * cos_t;
        let e = rel_err(got, want);
        worst = worst.max(e);
        assert!(e < 1e-6, "p = {p}: {got} vs {want} (rel {e:e})");
    }
    println!("sphere above horizon: worst relative error {worst:e}");
}

#[test]
fn sphere_crossing_the_horizon_matches_dense_quadrature() {
    let light = sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, Vec3::ONE);
    let mut worst = 0.0f64;
    for (p, n) in [
        (Vec3::new(3.0, 0.0, 0.0), Vec3::Y), // centre on the horizon
        (Vec3::new(2.0, 0.5, 1.0), Vec3::new(0.0, 1.0, 0.3)),
        (Vec3::new(0.0, -0.2, 0.0), Vec3::new(0.9, 0.3, 0.0)), // close, cone 78°
        (Vec3::new(4.0, 1.3, 0.0), Vec3::Y),                   // mostly below
    ] {
        let sp = lambert(p, n);
        let got = f64::from(unshadowed_direct(&light, &[], &sp).x);
        let want = quad_sphere(&light, &sp, 2000, 2000).x;
        let e = rel_err(got, want);
        worst = worst.max(e);
        assert!(e < 1e-5, "p = {p}, n = {n}: {got} vs {want} (rel {e:e})");
    }
    // Entirely below the horizon, and inside the sphere: nothing.
    let below = lambert(Vec3::new(0.0, 3.0, 0.0), Vec3::Y);
    assert_eq!(unshadowed_direct(&light, &[], &below), Vec3::ZERO);
    let inside = lambert(Vec3::new(0.1, 1.2, 0.0), Vec3::Y);
    assert_eq!(unshadowed_direct(&light, &[], &inside), Vec3::ZERO);
    println!("sphere crossing horizon: worst relative error {worst:e} (vs 2000² quadrature)");
}

/// Worst error of the specular integration over `receivers` (position,
/// normal, toward-eye) against brute-force quadrature: relative to the
/// reference, or to 1 % of the largest reference among the receivers when
/// only the lobe's far tail (values down to 1e-46) reaches the light, where
/// a relative figure would measure nothing visible.
fn specular_errors(light: &Light, receivers: &[(Vec3, Vec3, Vec3)], ns: f32) -> f64 {
    let pairs: Vec<(f64, f64)> = receivers
        .iter()
        .map(|&(p, n, wo)| {
            let sp = glossy(p, n, wo, 0.0, 1.0, ns);
            let got = d(unshadowed_direct(light, &[], &sp)).x;
            let want = match light.shape {
                LightShape::Rect { .. } => quad_rect(light, None, &sp, 1200, 1200).x,
                LightShape::Sphere { .. } => quad_sphere(light, &sp, 1500, 1500).x,
            };
            assert!(want > 0.0, "test set-up: receiver {p} must see the lobe");
            (got, want)
        })
        .collect();
    let peak = pairs.iter().map(|&(_, w)| w).fold(0.0, f64::max);
    pairs
        .iter()
        .map(|&(got, want)| (got - want).abs() / want.max(0.01 * peak))
        .fold(0.0, f64::max)
}

#[test]
fn specular_lobe_matches_dense_quadrature() {
    // A 2 × 1.6 light at height 2 (subtends about 50° from below), and a
    // sphere light of radius 0.8 at the same place.
    let light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::X,
        Vec3::Z * 0.8,
        false,
        Vec3::ONE,
    );
    let ball = sphere(Vec3::new(0.0, 2.0, 0.0), 0.8, Vec3::ONE);
    let small_light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::X * 0.1,
        Vec3::Z * 0.08,
        false,
        Vec3::ONE,
    );
    let small_ball = sphere(Vec3::new(0.0, 2.0, 0.0), 0.1, Vec3::ONE);
    let common = [
        // Mirror direction through the light's centre: the lobe's peak.
        (Vec3::new(0.0, 0.0, 1.0), Vec3::Y, Vec3::new(0.0, 2.0, 1.0)),
        (
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.1, 1.0, 0.0),
            Vec3::new(-0.4, 1.0, -0.6),
        ),
        // Lobe off the light: only its tail reaches it.
        (Vec3::new(0.0, 0.0, 1.0), Vec3::Y, Vec3::new(0.0, 1.0, -1.0)),
    ];
    // Receivers whose horizon cuts the large lights.
    let rect_cut = (
        Vec3::new(-0.5, 1.5, 0.0),
        Vec3::new(1.0, 0.4, 0.0),
        Vec3::new(1.0, -0.2, 0.3),
    );
    // (wo away from -wi: near wi = -wo the half vector, and so the lobe,
    // turns abruptly, which no 16 x 16 rule resolves.)
    let ball_cut = (
        Vec3::new(-1.5, 2.0, 0.0),
        Vec3::new(0.1, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.2),
    );
    let rect_rx: Vec<_> = common.iter().copied().chain([rect_cut]).collect();
    let ball_rx: Vec<_> = common.iter().copied().chain([ball_cut]).collect();
    // Tolerances: what the cell rules achieve (measured values in
    // docs/shading.md), with a margin of about 3×. Cells are sized to the
    // lobe up to 16 per axis, so the error grows once a narrow lobe
    // (Ns = 1000) meets a large light.
    for (ns, tol_rect, tol_sphere) in [
        (1.0, 3e-5, 2e-4),
        (10.0, 1.5e-4, 1.5e-4),
        (50.0, 1e-4, 1.5e-4),
        (200.0, 1e-4, 5e-5),
        (1000.0, 1.5e-2, 2e-3),
    ] {
        let er = specular_errors(&light, &rect_rx, ns);
        let es = specular_errors(&ball, &ball_rx, ns);
        println!("specular Ns = {ns}: rect {er:e}, sphere {es:e}");
        // Small lights (about 6° across, few cells) at the same places.
        let ers = specular_errors(&small_light, &rect_rx, ns);
        let ess = specular_errors(&small_ball, &ball_rx, ns);
        println!("specular Ns = {ns}: small rect {ers:e}, small sphere {ess:e}");
        assert!(ers < tol_rect, "small rect, Ns = {ns}: {ers:e}");
        assert!(ess < tol_sphere, "small sphere, Ns = {ns}: {ess:e}");
        assert!(er < tol_rect, "rect, Ns = {ns}: {er:e}");
        assert!(es < tol_sphere, "sphere, Ns = {ns}: {es:e}");
    }
}

/// A deterministic pseudo-random RGB texture (values in [0.05, 1.05]).
fn noise_texture(w: u32, h: u32, seed: u64) -> Texture {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) + 0.05
    };
    let data = (0..w * h)
        .map(|_| Vec3::new(next(), next(), next()))
        .collect();
    Texture {
        path: "noise.png".into(),
        width: w,
        height: h,
        data: TextureData::Rgb(data),
    }
}

#[test]
fn textured_rect_matches_dense_quadrature() {
    let mut light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::X,
        Vec3::Z * 0.8,
        false,
        Vec3::splat(2.0),
    );
    light.texture = Some(0);
    let receivers = [
        lambert(Vec3::ZERO, Vec3::Y),
        lambert(Vec3::new(0.7, 1.2, 0.3), Vec3::new(-0.5, 1.0, 0.0)),
        lambert(Vec3::new(-2.0, 0.5, 0.0), Vec3::new(1.0, 1.0, 0.0)),
    ];
    // Small texture: cells are texels, so the diffuse part is exact.
    let small = [noise_texture(4, 3, 1)];
    let mut worst_small = 0.0f64;
    for sp in &receivers {
        let got = d(unshadowed_direct(&light, &small, sp));
        let want = quad_rect(&light, small.first(), sp, 2000, 1998);
        for k in 0..3 {
            worst_small = worst_small.max(rel_err(got[k], want[k]));
        }
    }
    assert!(worst_small < 1e-5, "4×3 texture: {worst_small:e}");
    // Large texture: 16 × 16 cells of mean radiance (the approximation).
    let large = [noise_texture(37, 23, 2)];
    let mut worst_large = 0.0f64;
    for sp in &receivers {
        let got = d(unshadowed_direct(&light, &large, sp));
        let want = quad_rect(&light, large.first(), sp, 37 * 54, 23 * 87);
        for k in 0..3 {
            worst_large = worst_large.max(rel_err(got[k], want[k]));
        }
    }
    assert!(worst_large < 3e-3, "37×23 texture: {worst_large:e}");
    // Textured and glossy together (texel-aligned 16 × 12 cells).
    let sp = glossy(
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::Y,
        Vec3::new(0.0, 2.0, 1.0),
        0.5,
        0.5,
        10.0,
    );
    let got = d(unshadowed_direct(&light, &small, &sp));
    let want = quad_rect(&light, small.first(), &sp, 2000, 1998);
    let worst_glossy = (0..3).map(|k| rel_err(got[k], want[k])).fold(0.0, f64::max);
    assert!(worst_glossy < 1e-5, "textured glossy: {worst_glossy:e}");
    println!(
        "textured rect: 4×3 {worst_small:e}, 37×23 {worst_large:e}, 4×3 glossy Ns=10 {worst_glossy:e}"
    );
}

/// `n × n` stratified (cell-midpoint) samples on a rect light.
fn rect_samples(light: &Light, n: usize) -> Vec<LightSample> {
    let LightShape::Rect { center, u, v, .. } = light.shape else {
        unreachable!()
    };
    let area = 4.0 * u.cross(v).length();
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let st = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            out.push(LightSample {
                x: center + u * (2.0 * st.x - 1.0) + v * (1.0 - 2.0 * st.y),
                st,
                inv_pdf_area: area,
            });
        }
    }
    out
}

/// `n × n` stratified samples over a sphere's whole surface (equal-area
/// cells in (z, φ)).
fn sphere_samples(light: &Light, n: usize) -> Vec<LightSample> {
    let LightShape::Sphere { center, radius } = light.shape else {
        unreachable!()
    };
    let area = 4.0 * std::f32::consts::PI * radius * radius;
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        let z = 1.0 - 2.0 * (j as f64 + 0.5) / n as f64;
        let rxy = (1.0 - z * z).sqrt();
        for i in 0..n {
            let phi = 2.0 * PI * (i as f64 + 0.5) / n as f64;
            let dir = DVec3::new(rxy * phi.cos(), rxy * phi.sin(), z).as_vec3();
            out.push(LightSample {
                x: center + dir * radius,
                st: Vec2::ZERO,
                inv_pdf_area: area,
            });
        }
    }
    out
}

#[test]
fn sample_estimator_converges_to_the_integrator() {
    let mut light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::X,
        Vec3::Z * 0.8,
        false,
        Vec3::splat(2.0),
    );
    let tex = [noise_texture(4, 3, 7)];
    let sp = glossy(
        Vec3::new(0.2, 0.0, 0.5),
        Vec3::new(0.1, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 1.0),
        0.7,
        0.3,
        8.0,
    );
    let samples = rect_samples(&light, 480);
    let ones = vec![1.0f32; samples.len()];
    let mut worst = 0.0f64;
    for textured in [false, true] {
        light.texture = textured.then_some(0);
        let exact = d(unshadowed_direct(&light, &tex, &sp));
        let est = d(direct_from_samples(&light, &tex, &sp, &samples, &ones));
        let prepared = PreparedLight::new(&light, &tex);
        assert_eq!(
            prepared.direct_from_samples(&sp, &samples, &ones),
            est.as_vec3()
        );
        for k in 0..3 {
            worst = worst.max(rel_err(est[k], exact[k]));
        }
        // Half the samples blocked, half transmitting 50 %: scales linearly.
        let vis: Vec<f32> = (0..samples.len()).map(|_| 0.5).collect();
        let half = d(direct_from_samples(&light, &tex, &sp, &samples, &vis));
        assert!((half * 2.0 - est).abs().max_element() <= 1e-6 * est.max_element());
    }
    assert!(worst < 1e-5, "rect estimator vs integrator: {worst:e}");

    let ball = sphere(Vec3::new(0.5, 2.0, 0.0), 0.7, Vec3::splat(3.0));
    let samples = sphere_samples(&ball, 600);
    let ones = vec![1.0f32; samples.len()];
    let est = d(direct_from_samples(&ball, &[], &sp, &samples, &ones)).x;
    let exact = d(unshadowed_direct(&ball, &[], &sp)).x;
    let e_sphere = rel_err(est, exact);
    assert!(
        e_sphere < 1e-5,
        "sphere estimator vs integrator: {e_sphere:e}"
    );
    println!("estimator vs integrator: rect {worst:e}, sphere {e_sphere:e}");

    // No samples, all blocked, and a receiver inside the sphere: zero.
    assert_eq!(direct_from_samples(&ball, &[], &sp, &[], &[]), Vec3::ZERO);
    let zeros = vec![0.0f32; samples.len()];
    assert_eq!(
        direct_from_samples(&ball, &[], &sp, &samples, &zeros),
        Vec3::ZERO
    );
    let inside = lambert(Vec3::new(0.5, 2.1, 0.0), Vec3::Y);
    assert_eq!(
        direct_from_samples(&ball, &[], &inside, &samples, &ones),
        Vec3::ZERO
    );
}

#[test]
fn degenerate_configurations_are_finite() {
    let (c, u, v) = (Vec3::new(0.0, 2.0, 0.0), Vec3::X, Vec3::Z * 0.5);
    let corner = c + u + v;
    let edge_mid = c + u;
    let lights = [
        rect(c, u, v, false, Vec3::ONE),
        rect(c, u, v, true, Vec3::ONE),
        sphere(c, 0.5, Vec3::ONE),
    ];
    let mut tex_light = rect(c, u, v, true, Vec3::ONE);
    tex_light.texture = Some(0);
    let tex = [noise_texture(40, 40, 3)];
    let points = [
        c,                              // in the plane, inside the rect / sphere centre
        corner,                         // at a corner
        edge_mid,                       // on an edge
        c + u * 3.0,                    // in the plane, outside
        c + Vec3::Y * 1e-7,             // just off the plane
        c - Vec3::Y * 1e-7 + u * 0.999, // just off the plane, near an edge
        corner + Vec3::new(1e-6, -1e-6, 0.0),
        c + Vec3::new(0.0, 0.5, 0.0), // on the sphere's surface
        c + Vec3::new(0.0, -0.5000001, 0.0),
        Vec3::new(1e6, -1e6, 1e6), // very far
    ];
    let normals = [
        Vec3::Y,
        -Vec3::Y,
        Vec3::X, // perpendicular to the light's normal
        Vec3::Z,
        Vec3::new(1.0, 1e-7, 0.0),
    ];
    for light in lights.iter().chain([&tex_light]) {
        let prepared = PreparedLight::new(light, &tex);
        for &p in &points {
            for &n in &normals {
                for sp in [
                    lambert(p, n),
                    glossy(p, n, -n, 0.5, 1.0, 0.0), // wo opposite n
                    glossy(p, n, Vec3::new(0.3, -1.0, 0.0), 0.5, 1.0, 1e4),
                ] {
                    let l = prepared.unshadowed_direct(&sp);
                    assert!(
                        l.is_finite() && l.min_element() >= 0.0,
                        "{light:?} p = {p} n = {n}: {l}"
                    );
                    let f = brdf(&sp, -sp.wo);
                    assert!(f.is_finite(), "brdf at wi = −wo: {f}");
                    let s = [LightSample {
                        x: corner,
                        st: Vec2::ONE,
                        inv_pdf_area: 1.0,
                    }];
                    let e = prepared.direct_from_samples(&sp, &s, &[1.0]);
                    assert!(e.is_finite() && e.min_element() >= 0.0, "{e}");
                }
            }
        }
    }
    // Exactly in the plane of a rect: cos_x = 0 everywhere.
    for light in &lights[..2] {
        assert_eq!(
            unshadowed_direct(light, &[], &lambert(c, Vec3::Y)),
            Vec3::ZERO
        );
        assert_eq!(
            unshadowed_direct(light, &[], &lambert(corner, Vec3::X)),
            Vec3::ZERO
        );
    }
}

#[test]
fn results_are_deterministic() {
    let mut light = rect(
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::X,
        Vec3::Z * 0.8,
        false,
        Vec3::ONE,
    );
    light.texture = Some(0);
    let tex = [noise_texture(64, 64, 9)];
    let sp = glossy(
        Vec3::new(0.3, 0.0, 0.1),
        Vec3::Y,
        Vec3::new(0.0, 1.0, 1.0),
        0.5,
        0.5,
        30.0,
    );
    let a = unshadowed_direct(&light, &tex, &sp);
    let b = PreparedLight::new(&light, &tex).unshadowed_direct(&sp);
    assert_eq!(
        a.to_array().map(f32::to_bits),
        b.to_array().map(f32::to_bits)
    );
}
