//! The cameras and `KHR_lights_punctual` lights of a glTF file, placed
//! by their nodes' world transforms, as data for the scene to use.

use super::data::err;
use super::Placed;
use crate::error::Result;
use glam::{Mat4, Vec3};
use gltf_json as json;
use json::validation::Checked;
use std::path::Path;

/// A camera of a glTF file, placed by its node.
#[derive(Debug, Clone, PartialEq)]
pub(in crate::scene) struct GltfCamera {
    /// The camera's name, else its node's.
    pub name: Option<String>,
    /// Eye position.
    pub eye: Vec3,
    /// Viewing direction (the node's -Z), unit length.
    pub forward: Vec3,
    /// Up direction (the node's +Y), unit length.
    pub up: Vec3,
    /// Vertical field of view in degrees (0 for an unsupported camera).
    pub yfov_degrees: f32,
    /// Width / height, when the file gives it.
    pub aspect: Option<f32>,
    /// Why the camera cannot be used (orthographic), if so.
    pub unsupported: Option<String>,
}

/// The kind of a punctual light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::scene) enum GltfLightKind {
    /// Emits in all directions from `position`.
    Point,
    /// A cone around `direction` from `position`.
    Spot {
        /// Angle from the axis where the falloff begins, radians.
        inner_cone_angle: f32,
        /// Angle from the axis where it ends, radians.
        outer_cone_angle: f32,
    },
    /// Parallel light along `direction`, from infinitely far.
    Directional,
}

/// A `KHR_lights_punctual` light, placed by its node.
#[derive(Debug, Clone, PartialEq)]
pub(in crate::scene) struct GltfLight {
    /// The light's name, else its node's.
    pub name: Option<String>,
    /// Point, spot or directional.
    pub kind: GltfLightKind,
    /// The node's origin.
    pub position: Vec3,
    /// The direction light travels (the node's -Z), unit length.
    pub direction: Vec3,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Candela (point, spot) or lux (directional).
    pub intensity: f32,
    /// Distance where the light's influence ends, if given.
    pub range: Option<f32>,
}

/// The position, forward (-Z) and up (+Y) of a node's world transform.
fn frame(world: &Mat4) -> (Vec3, Vec3, Vec3) {
    (
        world.transform_point3(Vec3::ZERO),
        world.transform_vector3(Vec3::NEG_Z).normalize_or_zero(),
        world.transform_vector3(Vec3::Y).normalize_or_zero(),
    )
}

/// The cameras of the placed nodes.
pub(super) fn cameras(
    path: &Path,
    root: &json::Root,
    placed: &[Placed],
) -> Result<Vec<GltfCamera>> {
    let mut out = Vec::new();
    for p in placed {
        let node = &root.nodes[p.node];
        let Some(c) = node.camera.map(|c| c.value()) else {
            continue;
        };
        let Some(camera) = root.cameras.get(c) else {
            return Err(err(
                path,
                &format!("/nodes/{}/camera", p.node),
                format!(
                    "camera {c} does not exist (the file has {})",
                    root.cameras.len()
                ),
            ));
        };
        let (eye, forward, up) = frame(&p.world);
        let orthographic = camera.type_ == Checked::Valid(json::camera::Type::Orthographic);
        let (yfov_degrees, aspect, unsupported) = match (&camera.perspective, orthographic) {
            (Some(persp), false) => (persp.yfov.to_degrees(), persp.aspect_ratio, None),
            (_, true) => (
                0.0,
                None,
                Some(format!(
                    "/cameras/{c} is orthographic; penumbra's camera is a perspective pinhole"
                )),
            ),
            (None, false) => (
                0.0,
                None,
                Some(format!("/cameras/{c} has no `perspective` parameters")),
            ),
        };
        out.push(GltfCamera {
            name: camera.name.clone().or_else(|| node.name.clone()),
            eye,
            forward,
            up,
            yfov_degrees,
            aspect,
            unsupported,
        });
    }
    Ok(out)
}

/// The `KHR_lights_punctual` lights of the placed nodes.
pub(super) fn lights(path: &Path, root: &json::Root, placed: &[Placed]) -> Result<Vec<GltfLight>> {
    use json::extensions::scene::khr_lights_punctual::Type as Kind;
    let defined = root
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .map_or(&[][..], |l| l.lights.as_slice());
    let mut out = Vec::new();
    for p in placed {
        let node = &root.nodes[p.node];
        let Some(l) = node
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map(|l| l.light.value())
        else {
            continue;
        };
        let at = format!("/nodes/{}/extensions/KHR_lights_punctual/light", p.node);
        let Some(light) = defined.get(l) else {
            return Err(err(
                path,
                &at,
                format!("light {l} does not exist (the file has {})", defined.len()),
            ));
        };
        let kind = match (light.type_, &light.spot) {
            (Checked::Valid(Kind::Point), _) => GltfLightKind::Point,
            (Checked::Valid(Kind::Directional), _) => GltfLightKind::Directional,
            (Checked::Valid(Kind::Spot), spot) => GltfLightKind::Spot {
                inner_cone_angle: spot.as_ref().map_or(0.0, |s| s.inner_cone_angle),
                outer_cone_angle: spot
                    .as_ref()
                    .map_or(std::f32::consts::FRAC_PI_4, |s| s.outer_cone_angle),
            },
            (Checked::Invalid, _) => {
                return Err(err(
                    path,
                    &format!("/extensions/KHR_lights_punctual/lights/{l}/type"),
                    "invalid light type",
                ))
            }
        };
        let (position, direction, _) = frame(&p.world);
        out.push(GltfLight {
            name: light.name.clone().or_else(|| node.name.clone()),
            kind,
            position,
            direction,
            color: Vec3::from(light.color),
            intensity: light.intensity,
            range: light.range,
        });
    }
    Ok(out)
}
