//! The integration tests, as one test binary: every file here is a
//! module (`cargo test --release --test it NAME::` runs one file's tests).
//! One binary instead of one per file: each test binary links the whole
//! crate, and linking fifty of them was most of CI's build time.

mod common;

mod adaptive_maps;
mod agreement;
mod cli;
mod cli_messages;
mod compare;
mod compare_api;
mod compare_shard;
mod compare_ux;
mod dabrovic;
mod dcs;
mod dcs_rays;
mod determinism;
mod diff;
mod exact_image;
mod far_from_origin;
mod flip;
mod fuzz;
mod golden;
mod import;
mod inputs;
mod large_series;
mod library;
mod light_reached;
mod light_view;
mod lighting;
mod mesh_formats;
mod metrics;
mod module_graph;
mod multi_map;
mod obj_quirks;
mod odd_scenes;
mod output;
mod output_safety;
mod patterns;
mod pcss;
mod penumbra_casting;
mod penumbra_casting_translucent;
mod progress;
mod progressive;
mod raster;
mod receive_shadows;
mod reference;
mod registry;
mod render_tiles;
mod scene_builder;
mod scene_loading;
mod shadow_map;
mod shadow_map_stiff;
mod shadow_volumes;
mod slurm;
mod soft_shadow_map;
mod stsv;
mod stsv_scenes;
mod transmittance;
mod verify;
mod wedges;
