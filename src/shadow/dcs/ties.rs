//! Receivers whose shadow-volume start count is a depth tie, and their
//! exact start counts by one ray to the light's centre.
//!
//! The stencil decides `D(O)` at the rasterized receiver `p` with a depth
//! test. When a volume face passes through `p` — the receiver's own face
//! on an open (Bergeron) caster, whose caps are the faces themselves, or
//! coplanar duplicate faces whose depths differ by rounding — that test is
//! a tie, and it may disagree with the shadow-ray origin `p'` the counters
//! follow. `p'` is on the viewer's side of the receiver's surface, so the
//! count it needs is the one of a receiver slightly *nearer* the eye.
//! Such receivers are found by counting once more with the scene depth
//! moved towards the eye by [`DEPTH_BAND`] (relative): where that count
//! differs from the stencil's, a volume face lies within the band behind
//! the depth-test tie. (A receiver on its own open face, rasterized from
//! the same triangle as the G-buffer, ties exactly, and the z-fail test
//! counts a face at equal depth as behind: already the nearer count, so it
//! is not flagged.) For those few pixels the start counts of every caster
//! group are recounted exactly at `p'`, by one ray to the centre through
//! the groups' faces, with the stencil's weights (closed caster: its
//! light-facing faces; open caster: every face).

use crate::error::Result;
use crate::geom::bvh::Bvh;
use crate::geom::{EdgeAdjacency, SceneGeometry};
use crate::raster::Framebuffer;
use crate::shadow::kit::volumes::{stencil_counts, ShadowVolume};
use glam::Vec3;

/// Relative depth band of the tie test: 64 f32 ulps, far above the
/// rounding difference of two coplanar triangles' depths.
pub const DEPTH_BAND: f32 = 4e-6;

/// Per pixel: does the count of `volume` change when the receiver moves
/// [`DEPTH_BAND`] nearer the eye than in `counts` (the stencil's counts
/// at the scene depth), or, with `both_sides`, when it moves that much
/// nearer or farther? `scene_depth` is the scene's depth (its stencil is
/// unused). Reversed Z: nearer is larger.
///
/// One side catches the ties the stencil resolved the wrong way for `p'`;
/// both sides also catch receivers where a face passes between the
/// view-ray point and `p'` (off the view ray, along the normal), at the
/// price of flagging every receiver on an open caster's own face (the
/// ground of most scenes), each then recounted by a ray.
pub fn tied_pixels(
    scene_depth: &Framebuffer,
    volume: &ShadowVolume,
    counts: &[i32],
    both_sides: bool,
) -> Result<Vec<bool>> {
    let shifted = |scale: f32| -> Result<Vec<i32>> {
        let mut fb = scene_depth.clone();
        fb.map_depth(|d| d * scale);
        stencil_counts(&mut fb, volume, false)
    };
    let nearer = shifted(1.0 + DEPTH_BAND)?;
    let mut tied: Vec<bool> = nearer.iter().zip(counts).map(|(a, b)| a != b).collect();
    if both_sides {
        let farther = shifted(1.0 - DEPTH_BAND)?;
        for (t, (a, b)) in tied.iter_mut().zip(farther.iter().zip(counts)) {
            *t |= a != b;
        }
    }
    Ok(tied)
}

/// No group.
const NONE: u32 = u32::MAX;

/// Exact start counts of every caster group at given points.
pub struct ExactStart {
    bvh: Bvh,
    /// Per scene triangle: `group << 1 | weight` (weight 1 when the face
    /// counts from the centre), or [`NONE`].
    table: Vec<u32>,
}

impl ExactStart {
    /// For `groups` (each: adjacency and its faces' light-facing flags
    /// from the centre).
    pub fn new(geometry: &SceneGeometry, groups: &[(&EdgeAdjacency, &[bool])]) -> ExactStart {
        let mut table = vec![NONE; geometry.triangles.len()];
        for (g, (adj, lit)) in groups.iter().enumerate() {
            for (slot, &f) in adj.faces.iter().enumerate() {
                let weight = if adj.face_closed[slot] {
                    u32::from(lit[slot])
                } else {
                    1
                };
                table[f as usize] = (g as u32) << 1 | weight;
            }
        }
        let bvh = Bvh::build(geometry, |t| table[t as usize] != NONE);
        ExactStart { bvh, table }
    }

    /// The start count of each group at `origin` for the light centre
    /// `centre`, into `out` (one entry per group).
    pub fn counts(&self, origin: Vec3, centre: Vec3, out: &mut [i32]) {
        out.fill(0);
        let dir = centre - origin;
        // Stop just short of the centre, as the reference's rays do.
        let t_max = (1.0 - crate::shadow::kit::rays::END_SHORTEN) as f32;
        self.bvh.for_each_hit(origin, dir, t_max, |h| {
            let e = self.table[h.triangle as usize];
            if e != NONE {
                if let Some(c) = out.get_mut((e >> 1) as usize) {
                    *c += (e & 1) as i32;
                }
            }
        });
    }
}
