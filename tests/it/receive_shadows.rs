//! `receive_shadows = false`: by the scene contract such a receiver's
//! Vcoef is 1 (no shadow on it), for every technique and in every layer a
//! user reads, not only in the radiance. Before one place set it after
//! every technique, dcs and the nine approximate techniques wrote the
//! ground's shadow into the `vcoef` layer (5.8 % of the pixels for dcs).

use crate::common;

use penumbra::internal::render::{render, Aov, RenderOptions};
use penumbra::internal::shadow::Technique;

const SCENE: &str = r#"
[camera]
eye = [0.0, 5.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y = 45
width = 48
height = 48
[[light]]
type = "LIGHT"
center = [0.0, 4.0, 0.0]
EXTENT
radiance = 10
[[object]]
name = "ground"
shape = "quad"
size = [6.0, 6.0]
receive_shadows = false
[[object]]
name = "occ"
shape = "box"
size = [1.0, 0.5, 1.0]
translate = [0.0, 1.0, 0.0]
"#;

#[test]
fn non_receivers_have_vcoef_one_for_every_technique() {
    let lights = [
        ("rect", "u = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]"),
        ("sphere", "radius = 0.5"),
    ];
    for (light, extent) in lights {
        let toml = SCENE.replace("LIGHT", light).replace("EXTENT", extent);
        let scene = common::scene_in_scratch(&format!("no-receive-{light}"), &toml, &[]);
        let frame = common::Frame::new(&scene, 48, 48);
        let ground: Vec<usize> = (0..48 * 48)
            .filter(|&i| {
                frame.gbuffer.is_surface(i)
                    && scene.objects[frame.gbuffer.sample(i).object as usize].name == "ground"
            })
            .collect();
        assert!(ground.len() > 48 * 48 / 3, "the ground fills the view");
        for technique in Technique::all() {
            let options = RenderOptions {
                technique,
                samples: 16,
                aovs: vec![Aov::Vcoef],
                ..RenderOptions::default()
            };
            let out = match render(&scene, &options) {
                Ok(out) => out,
                // A technique that refuses the light (said by the registry).
                Err(e) => {
                    assert!(e.to_string().contains("cannot render"), "{e}");
                    continue;
                }
            };
            let layer = out
                .layers
                .iter()
                .find(|l| l.name == "vcoef")
                .expect("vcoef layer");
            let vcoef = &layer.channels[0].1;
            let shadowed = ground.iter().filter(|&&i| vcoef[i] != 1.0).count();
            assert_eq!(
                shadowed,
                0,
                "{} ({light} light): {shadowed} ground pixels with Vcoef below 1",
                technique.name()
            );
            // The box still shadows itself where it receives.
            let lights_term = out.lights[0].vcoef();
            assert!(ground.iter().all(|&i| lights_term[i] == 1.0));
        }
    }
}
