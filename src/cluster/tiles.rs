//! `render --tiles I/N` and `merge-tiles`: one image rendered as N
//! horizontal bands on N machines, assembled into the PNG and EXR a
//! single-machine render writes, byte for byte.
//!
//! **Why a band has the single render's bits.** A band render runs the
//! whole pipeline on the *full* view: the same geometry, the same G-buffer
//! pass over the whole frame (so clipping, the guard band, snapping, tile
//! binning and the depth buffer are those of the full render: nothing
//! depends on the band), and then marks every G-buffer pixel outside the
//! band's rows (plus a margin, below) as background
//! ([`GBuffer::keep_rows`](crate::gbuffer::GBuffer::keep_rows)) before the
//! shadow technique runs: [`render_rows`], `render`'s own pipeline. A
//! technique whose result at a pixel depends only
//! on that pixel's G-buffer sample, the full-frame depth buffer, the scene
//! and the per-pixel-keyed seeds then computes the same bits at every
//! pixel of the band, and skips the work of the others (the ray-traced
//! reference and DCS trace nothing for background pixels: that is the
//! saving). Shading is per pixel. The band's rows are then cut out.
//!
//! A technique that looks at *other* pixels needs those to be real:
//! [`kept_rows`] widens the band to the rows it reads, or refuses the
//! technique with the reason. `tests/it/render_tiles.rs` holds every
//! registered technique to this: band by band, the assembled image equals
//! the single render's bytes, or the technique is refused.
//!
//! Bands are whole rows of the rasterizer's 64×64 tiles, so that a band
//! boundary never splits a tile (raster work is per tile; the tile grid of
//! every band render is the full frame's) and bands are balanced to within
//! one tile row.
//!
//! A part file is `PENUMBRA-TILE 2\n`, one line of JSON ([`PartHeader`]:
//! full size, band rows, scene hash, options, version, channel names, the
//! CRC-32 of the data), then the band's channels as little-endian `f32`,
//! channel after channel. It is written atomically. The checksum catches
//! a part damaged at the same length (a copy gone wrong, a bad disk),
//! which would otherwise merge into a plausible but different image;
//! format 1 (without it) is refused.

use crate::compare::cache::{hash_scene, StableHasher};
use crate::error::{Error, Result};
use crate::output::{image_outputs, write_atomically, Layer, OutputSet};
use crate::raster::{MAX_SIDE, TILE_SIZE};
use crate::render::{render_rows, view_for, Render, RenderOptions};
use crate::report::Progress;
use crate::scene::Scene;
use crate::shadow::technique::Bands;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The part format this penumbra writes and reads (2: with a checksum).
const FORMAT: u32 = 2;

/// First line of a part file: `PENUMBRA-TILE {FORMAT}`.
const MAGIC: &[u8] = b"PENUMBRA-TILE 2\n";

/// The start of the first line of every format.
const MAGIC_PREFIX: &[u8] = b"PENUMBRA-TILE ";

/// `I/N` with `1 <= I <= N`, as `(I, N)`; `what` names the option.
pub fn parse_share(what: &str, s: &str) -> Result<(u32, u32)> {
    crate::compare::share::parse_share(s)
        .map_err(|_| Error::param(what, format!("`{s}` is not I/N with 1 <= I <= N")))
}

/// Rows of band `index` (1-based) of `count` over an image `height` rows
/// high: whole tile rows, the tile rows split as evenly as integers allow.
/// An error when there are more bands than tile rows.
pub fn band_rows(height: u32, index: u32, count: u32) -> Result<Range<u32>> {
    let tile = TILE_SIZE as u64;
    let tile_rows = (u64::from(height)).div_ceil(tile);
    if count == 0 || index == 0 || index > count {
        return Err(Error::param(
            "--tiles",
            format!("{index}/{count} is not I/N with 1 <= I <= N"),
        ));
    }
    if u64::from(count) > tile_rows {
        return Err(Error::param(
            "--tiles",
            format!(
                "{count} bands, but {height} rows make only {tile_rows} bands of whole \
                 {tile}-row tiles"
            ),
        ));
    }
    let edge = |k: u64| ((k * tile_rows / u64::from(count)) * tile).min(u64::from(height)) as u32;
    Ok(edge(u64::from(index) - 1)..edge(u64::from(index)))
}

/// The rows a band render keeps real (the band, widened where the
/// technique's result at a band pixel reads other pixels; the band is
/// rendered with them and cropped), or why the technique cannot render
/// bands.
pub fn kept_rows(options: &RenderOptions, rows: Range<u32>, height: u32) -> Result<Range<u32>> {
    let technique = options.technique;
    let refuse = |why: &str| {
        Err(Error::param(
            "--tiles",
            format!(
                "{} cannot render bands: {why}; render it on one machine",
                technique.name()
            ),
        ))
    };
    // Each technique says in the registry (tests/it/render_tiles.rs checks
    // the claim: a band's pixels equal the whole frame's).
    match technique.info().bands {
        Bands::Rows => Ok(rows),
        Bands::Chunks(side) => {
            let side = side(&options.options).max(1);
            let first = rows.start / side * side;
            let end = rows.end.div_ceil(side).saturating_mul(side).min(height);
            Ok(first..end)
        }
        Bands::Refused(why) => refuse(why),
    }
}

/// Everything a part file says about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// `penumbra` version that rendered it.
    pub version: String,
    /// The scene's name.
    pub scene: String,
    /// Stable hash of the loaded scene's contents (hex).
    pub scene_hash: String,
    /// The render options that decide the bits (not the thread count).
    pub options: String,
    /// Full image width.
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// Band index, 1-based.
    pub index: u32,
    /// Number of bands.
    pub count: u32,
    /// The band's rows, `[first, end)`.
    pub rows: [u32; 2],
    /// Layers after radiance: `(layer name, channel names)`.
    pub layers: Vec<(String, Vec<String>)>,
    /// CRC-32 (IEEE) of the data after the header line, 8 hex digits.
    pub crc32: String,
}

/// A part file read back.
#[derive(Debug, Clone)]
pub struct Part {
    /// Its header.
    pub header: PartHeader,
    /// The band's radiance, row-major.
    pub radiance: Vec<Vec3>,
    /// The band's layers, in header order.
    pub layers: Vec<Layer>,
}

/// The hex scene hash a part records.
pub fn scene_hash(scene: &Scene) -> String {
    let mut h = StableHasher::default();
    hash_scene(&mut h, scene);
    format!("{:016x}", h.finish())
}

/// Renders band `index` of `count` of `scene` and writes it as a part
/// file at `path` (atomically).
pub fn render_part(
    scene: &Scene,
    options: &RenderOptions,
    index: u32,
    count: u32,
    path: &Path,
    progress: &Progress,
) -> Result<PartHeader> {
    let view = view_for(scene, options)?;
    let rows = band_rows(view.height, index, count)?;
    let kept = kept_rows(options, rows.clone(), view.height)?;
    let Render {
        radiance, layers, ..
    } = render_rows(scene, options, progress, Some(kept))?;

    let width = view.width as usize;
    let cut = (rows.start as usize * width)..(rows.end as usize * width);
    let mut data = Vec::new();
    let mut put = |values: &mut dyn Iterator<Item = f32>| {
        for v in values {
            data.extend(v.to_le_bytes());
        }
    };
    let band = &radiance[cut.clone()];
    put(&mut band.iter().map(|c| c.x));
    put(&mut band.iter().map(|c| c.y));
    put(&mut band.iter().map(|c| c.z));
    for layer in &layers {
        for (_, values) in &layer.channels {
            put(&mut values[cut.clone()].iter().copied());
        }
    }
    let header = PartHeader {
        version: env!("CARGO_PKG_VERSION").to_string(),
        scene: scene.name.clone(),
        scene_hash: scene_hash(scene),
        options: options_key(options),
        width: view.width,
        height: view.height,
        index,
        count,
        rows: [rows.start, rows.end],
        layers: layers
            .iter()
            .map(|l| {
                (
                    l.name.clone(),
                    l.channels.iter().map(|(c, _)| c.clone()).collect(),
                )
            })
            .collect(),
        crc32: crc32_hex(&data),
    };
    let mut bytes = MAGIC.to_vec();
    bytes.extend(serde_json::to_vec(&header).map_err(|e| Error::param("--tiles", e.to_string()))?);
    bytes.push(b'\n');
    bytes.extend(data);
    write_atomically(path, |tmp| {
        std::fs::write(tmp, &bytes).map_err(|e| Error::io(tmp, e))
    })?;
    Ok(header)
}

/// The options that decide a render's bits, as text two parts must share
/// (the thread count does not change them and is not included).
pub fn options_key(options: &RenderOptions) -> String {
    format!(
        "width={:?} height={:?} aovs={:?} technique={} samples={} seed={} pattern={:?} \
         options={:?}",
        options.width,
        options.height,
        options.aovs,
        options.technique.name(),
        options.samples,
        options.seed,
        options.pattern,
        options.options
    )
}

/// The CRC-32 of `data` as a part records it.
fn crc32_hex(data: &[u8]) -> String {
    format!("{:08x}", crc32fast::hash(data))
}

/// Reads a part file: refuses another format, a damaged header, a size
/// that does not match it, and data whose checksum does not.
pub fn read_part(path: &Path) -> Result<Part> {
    let bytes = crate::scene::input::read(path).map_err(|e| Error::io(path, e))?;
    let bad = |m: &str| Error::file(path, None, format!("not a penumbra tile part: {m}"));
    let rest = match bytes.strip_prefix(MAGIC) {
        Some(rest) => rest,
        None => {
            let Some(other) = bytes.strip_prefix(MAGIC_PREFIX) else {
                return Err(bad(&format!("no PENUMBRA-TILE {FORMAT} header")));
            };
            let line = other.split(|&b| b == b'\n').next().unwrap_or_default();
            let version = String::from_utf8_lossy(&line[..line.len().min(20)]);
            return Err(Error::file(
                path,
                None,
                format!(
                    "part format {version}, this penumbra reads format {FORMAT} only \
                     (format 2 adds a checksum); render the band again with this penumbra"
                ),
            ));
        }
    };
    let end = rest
        .iter()
        .position(|&b| b == b'\n')
        .ok_or_else(|| bad("unterminated header"))?;
    let header: PartHeader =
        serde_json::from_slice(&rest[..end]).map_err(|e| bad(&e.to_string()))?;
    let data = &rest[end + 1..];
    let [y0, y1] = header.rows;
    if !(1..=MAX_SIDE).contains(&header.width) || !(1..=MAX_SIDE).contains(&header.height) {
        return Err(bad("image size outside 1..=MAX_SIDE"));
    }
    match band_rows(header.height, header.index, header.count) {
        Ok(r) if [r.start, r.end] == header.rows => {}
        _ => {
            return Err(Error::file(
                path,
                None,
                format!(
                    "band {}/{} holds rows {:?}, not the rows of that band of a {}-row image",
                    header.index, header.count, header.rows, header.height
                ),
            ))
        }
    }
    let n = header.width as usize * (y1 - y0) as usize;
    let channels = 3 + header.layers.iter().map(|(_, c)| c.len()).sum::<usize>();
    if data.len() != n * channels * 4 {
        return Err(bad(&format!(
            "{} data bytes, the header's {channels} channels of {n} pixels need {} \
             (truncated?)",
            data.len(),
            n * channels * 4
        )));
    }
    let crc = crc32_hex(data);
    if crc != header.crc32 {
        return Err(Error::file(
            path,
            None,
            format!(
                "damaged: its data's CRC-32 is {crc}, the header says {:?}; render band \
                 {}/{} again",
                header.crc32, header.index, header.count
            ),
        ));
    }
    let mut planes = data.chunks_exact(n * 4).map(|c| {
        c.chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect::<Vec<f32>>()
    });
    let (r, g, b) = (
        planes.next().unwrap_or_default(),
        planes.next().unwrap_or_default(),
        planes.next().unwrap_or_default(),
    );
    let radiance = (0..n).map(|i| Vec3::new(r[i], g[i], b[i])).collect();
    let layers = header
        .layers
        .iter()
        .map(|(name, names)| Layer {
            name: name.clone(),
            channels: names
                .iter()
                .map(|c| (c.clone(), planes.next().unwrap_or_default()))
                .collect(),
        })
        .collect();
    Ok(Part {
        header,
        radiance,
        layers,
    })
}

/// Assembles part files into the full image at `output`, PNG or EXR
/// (radiance and every layer) by its extension, and also an EXR at `exr`;
/// all outputs or none. Refuses a missing, duplicated, mismatched or
/// damaged band, naming it, and an output that is one of the parts.
pub fn merge_parts(paths: &[PathBuf], output: &Path, exr: Option<&Path>) -> Result<PartHeader> {
    let first_path = paths
        .first()
        .ok_or_else(|| Error::param("merge-tiles", "no part files given"))?;
    // Before reading anything: the parts are inputs, never outputs.
    let images = image_outputs(output, exr, paths)?;
    let parts = paths
        .iter()
        .map(|p| read_part(p))
        .collect::<Result<Vec<Part>>>()?;
    let first = &parts[0].header;
    let mut seen: Vec<Option<&Path>> = vec![None; first.count as usize];
    for (part, path) in parts.iter().zip(paths) {
        let h = &part.header;
        let differs = |what: &str, a: &str, b: &str| {
            Error::file(
                path,
                None,
                format!(
                    "{what} differs from {}'s: {a:?} against {b:?}; parts of different \
                     renders cannot be merged",
                    first_path.display()
                ),
            )
        };
        for (what, a, b) in [
            ("version", &h.version, &first.version),
            ("scene hash", &h.scene_hash, &first.scene_hash),
            ("render options", &h.options, &first.options),
        ] {
            if a != b {
                return Err(differs(what, a, b));
            }
        }
        if (h.width, h.height, h.count) != (first.width, first.height, first.count) {
            return Err(differs(
                "image size or band count",
                &format!("{}x{} in {} bands", h.width, h.height, h.count),
                &format!("{}x{} in {} bands", first.width, first.height, first.count),
            ));
        }
        if h.layers != first.layers {
            return Err(differs(
                "layer list",
                &format!("{:?}", h.layers),
                &format!("{:?}", first.layers),
            ));
        }
        let slot = &mut seen[h.index as usize - 1];
        if let Some(other) = slot {
            return Err(Error::file(
                path,
                None,
                format!(
                    "band {}/{} is also in {}: each band once",
                    h.index,
                    h.count,
                    other.display()
                ),
            ));
        }
        *slot = Some(path);
    }
    let missing: Vec<String> = seen
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_none())
        .map(|(k, _)| {
            let k = k as u32 + 1;
            let rows = band_rows(first.height, k, first.count).unwrap_or(0..0);
            format!("{k}/{} (rows {}..{})", first.count, rows.start, rows.end)
        })
        .collect();
    if !missing.is_empty() {
        return Err(Error::param(
            "merge-tiles",
            format!(
                "missing band{} {}; render {} with --tiles and merge again",
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", "),
                if missing.len() > 1 { "them" } else { "it" }
            ),
        ));
    }
    let (w, h) = (first.width as usize, first.height as usize);
    let mut radiance = vec![Vec3::ZERO; w * h];
    let mut layers: Vec<Layer> = parts[0]
        .layers
        .iter()
        .map(|l| Layer {
            name: l.name.clone(),
            channels: l
                .channels
                .iter()
                .map(|(c, _)| (c.clone(), vec![0.0; w * h]))
                .collect(),
        })
        .collect();
    for part in &parts {
        let start = part.header.rows[0] as usize * w;
        let n = part.radiance.len();
        radiance[start..start + n].copy_from_slice(&part.radiance);
        for (dst, src) in layers.iter_mut().zip(&part.layers) {
            for ((_, d), (_, s)) in dst.channels.iter_mut().zip(&src.channels) {
                d[start..start + n].copy_from_slice(s);
            }
        }
    }
    let mut outputs = OutputSet::new();
    for (path, format) in &images {
        outputs.image(path, *format, first.width, first.height, &radiance, &layers)?;
    }
    outputs.commit()?;
    Ok(first.clone())
}

/// `penumbra merge-tiles`: its command line.
#[derive(Debug, Clone, clap::Args)]
pub struct MergeArgs {
    /// Part files written by `render --tiles I/N` (any order, every band
    /// once).
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output image, in the format of its extension: .png or .exr
    /// (radiance and the parts' layers). Never one of the parts.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also an EXR (radiance and the parts' layers), beside the -o image;
    /// all outputs are written, or none.
    #[arg(long)]
    pub exr: Option<PathBuf>,
}

/// Runs `merge-tiles`.
pub fn run_merge(args: &MergeArgs) -> Result<()> {
    let h = merge_parts(&args.parts, &args.output, args.exr.as_deref())?;
    crate::output::write_stderr(&format!(
        "penumbra: {} bands of {} ({}x{}) merged into {}\n",
        h.count,
        h.scene,
        h.width,
        h.height,
        args.output.display()
    ));
    Ok(())
}
