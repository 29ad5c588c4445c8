//! OpenEXR: linear `f32` channels in one part, ZIP-compressed scan lines
//! (lossless, so values read back bit-identical), row 0 at the top.

use super::{check_size, Layer, LoadedImage, OutputSet};
use crate::error::{Error, Result};
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, LayerAttributes, ReadChannels,
    ReadLayers, SmallVec, Text, WritableImage,
};
use glam::Vec3;
use std::collections::HashSet;
use std::fs::File;
use std::io::Cursor;
use std::path::Path;

/// Writes `radiance` as channels `R, G, B` plus every layer's channels as
/// `<layer>.<channel>`, all linear `f32`, at `path`, atomically (see
/// [`write_atomically`](super::write_atomically)).
///
/// Every channel must hold `width × height` values (row-major, row 0 at
/// the top) and full names must be distinct and Latin-1 (an EXR limit);
/// otherwise nothing is written and the error names `path`.
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    radiance: &[Vec3],
    layers: &[Layer],
) -> Result<()> {
    let mut set = OutputSet::new();
    stage_exr(&mut set, path, width, height, radiance, layers)?;
    set.commit()
}

/// [`write_exr`] into `set`.
pub(super) fn stage_exr(
    set: &mut OutputSet,
    path: &Path,
    width: u32,
    height: u32,
    radiance: &[Vec3],
    layers: &[Layer],
) -> Result<()> {
    check_size(path, width, height, radiance.len(), "radiance")?;
    let plane = |f: fn(&Vec3) -> f32| FlatSamples::F32(radiance.iter().map(f).collect());
    let mut channels = vec![
        ("R".to_string(), plane(|c| c.x)),
        ("G".to_string(), plane(|c| c.y)),
        ("B".to_string(), plane(|c| c.z)),
    ];
    for layer in layers {
        for (name, values) in &layer.channels {
            let full = format!("{}.{}", layer.name, name);
            check_size(
                path,
                width,
                height,
                values.len(),
                &format!("channel {full}"),
            )?;
            channels.push((full, FlatSamples::F32(values.clone())));
        }
    }
    let mut seen = HashSet::new();
    let mut list = Vec::with_capacity(channels.len());
    for (name, samples) in channels {
        if !seen.insert(name.clone()) {
            return Err(Error::file(
                path,
                None,
                format!("channel {name} appears twice"),
            ));
        }
        let text = Text::new_or_none(&name).ok_or_else(|| {
            Error::file(
                path,
                None,
                format!("channel name {name:?} has characters EXR cannot store"),
            )
        })?;
        list.push(AnyChannel::new(text, samples));
    }
    let mut attributes = LayerAttributes::default();
    for (name, value) in &set.exr_metadata {
        let (Some(name), Some(value)) = (Text::new_or_none(name), Text::new_or_none(value)) else {
            return Err(Error::file(
                path,
                None,
                format!("metadata {name:?} has characters EXR cannot store"),
            ));
        };
        attributes
            .other
            .insert(name, exr::meta::attribute::AttributeValue::Text(value));
    }
    let layer = exr::image::Layer::new(
        (width as usize, height as usize),
        attributes,
        // ZIP over 16 scan lines, increasing y: lossless and compact.
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let image = Image::from_layer(layer);
    set.stage(path, |tmp| {
        let file = File::create(tmp).map_err(|e| Error::io(tmp, e))?;
        image
            .write()
            .to_unbuffered(file)
            .map_err(|e| exr_error(tmp, e))
    })
}

/// An `exr` crate error as ours, at `path`.
fn exr_error(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(io) => Error::io(path, io),
        other => Error::file(path, None, format!("OpenEXR: {other}")),
    }
}

/// Decodes EXR `bytes` read from `path`: every channel of every part (at
/// full resolution), named `<part>.<channel>` when the part has a name.
/// All parts must have the same size.
pub(super) fn read_exr(path: &Path, bytes: Vec<u8>) -> Result<LoadedImage> {
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| exr_error(path, e))?;
    let mut size = None;
    let mut channels = Vec::new();
    for layer in &image.layer_data {
        let s = (layer.size.0, layer.size.1);
        if *size.get_or_insert(s) != s {
            return Err(Error::file(
                path,
                None,
                "parts of different sizes are not supported",
            ));
        }
        for ch in &layer.channel_data.list {
            let name = match &layer.attributes.layer_name {
                Some(part) => format!("{}.{}", part, ch.name),
                None => ch.name.to_string(),
            };
            channels.push((name, ch.sample_data.values_as_f32().collect()));
        }
    }
    let (w, h) = size.unwrap_or((0, 0));
    let dim = |v: usize| u32::try_from(v).map_err(|_| Error::file(path, None, "image too large"));
    Ok(LoadedImage {
        width: dim(w)?,
        height: dim(h)?,
        channels,
    })
}
