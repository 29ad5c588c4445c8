//! Legal scenes that render (partly) black for a reason the author may
//! not expect: no light, a one-sided rect light facing away from every
//! object, surfaces the camera sees through (opacity below 0.5). Each is
//! a warning, not an error (docs/scene-format.md, "Scenes that render
//! black").

use super::{LightShape, Scene};
use glam::Vec3;

/// One sentence per surprise in `scene`, in scene order.
pub fn warnings(scene: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    if scene.lights.is_empty() {
        let lit = if scene.ambient == Vec3::ZERO {
            "the image is black"
        } else {
            "only `ambient` lights the image"
        };
        out.push(format!("the scene has no [[light]]: {lit}"));
    }
    for (k, light) in scene.lights.iter().enumerate() {
        let LightShape::Rect {
            center,
            u,
            v,
            two_sided: false,
        } = light.shape
        else {
            continue;
        };
        // The emitting side is that of cross(u, v): an object lit by this
        // light has a vertex strictly in front of its plane.
        let n = u.cross(v);
        let lights_something = scene
            .objects
            .iter()
            .flat_map(|o| o.mesh.positions.iter())
            .any(|&p| n.dot(p - center) > 0.0);
        if !lights_something {
            let n = n.normalize_or_zero();
            out.push(format!(
                "light[{k}] (rect) emits only on the side of cross(u, v) = [{:.3}, {:.3}, {:.3}], \
                 and no object is on that side: it lights nothing (swap `u` and `v`, or set \
                 `two_sided = true`)",
                n.x, n.y, n.z
            ));
        }
    }
    for (i, object) in scene.objects.iter().enumerate() {
        // Opacity textures only lower a material's opacity (d × map_d), so
        // a material with `opacity` below 0.5 is see-through everywhere.
        let invisible = (object.mesh.material_ids.iter())
            .filter(|&&m| {
                scene
                    .materials
                    .get(m as usize)
                    .is_some_and(|m| m.opacity < 0.5)
            })
            .count();
        if invisible == 0 {
            continue;
        }
        let total = object.mesh.material_ids.len();
        let which = if invisible == total {
            "its triangles have".to_string()
        } else {
            format!("{invisible} of its {total} triangles have")
        };
        out.push(format!(
            "object[{i}] `{}`: {which} opacity below 0.5, so the camera sees through them \
             (they still cast their partial shadow)",
            object.name
        ));
    }
    out
}
