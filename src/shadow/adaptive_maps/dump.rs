//! Debug dump of the subdivision's evidence (`PENUMBRA_ADAPTIVE_DUMP=dir`):
//! per light the hard-test bits of every decision-grid point for every
//! receiver, the receivers' G-buffer data and the light points, so that
//! `scripts/adaptive-dump.py` can rebuild each quad's counts, mark its
//! failing receivers in an image and classify them. Off unless the
//! variable is set; it never changes the result (the extra maps it renders
//! for the points the subdivision did not test are not counted).

use crate::error::{Error, Result};
use crate::gbuffer::GBuffer;
use glam::Vec3;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The dump directory, when `PENUMBRA_ADAPTIVE_DUMP` names one.
pub fn dir() -> Option<PathBuf> {
    std::env::var_os("PENUMBRA_ADAPTIVE_DUMP")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(bytes))
        .map_err(|e| Error::io(path, e))
}

/// What one light's dump holds.
pub struct LightDump<'a> {
    /// Light index.
    pub light: usize,
    /// The G-buffer.
    pub gbuffer: &'a GBuffer,
    /// Receivers facing the light.
    pub active: &'a [bool],
    /// Receivers read by the comparison target.
    pub compared: &'a [bool],
    /// Comparison target size.
    pub target: (usize, usize),
    /// Decision bits, `words` u64 per receiver.
    pub bits: &'a [u64],
    /// Bias-ambiguity bits, same layout (empty: no band).
    pub ambiguous: &'a [u64],
    /// Words per receiver.
    pub words: usize,
    /// Decision grid side (points).
    pub grid: u32,
    /// World position of each decision point (row-major, `grid²`).
    pub points: Vec<Vec3>,
    /// Options, for the record.
    pub note: String,
}

/// Writes `light{k}-meta.json`, `light{k}-bits.bin` (u64 LE per word),
/// `light{k}-ambiguous.bin` (same layout; empty without the bias band) and
/// `light{k}-gbuffer.bin` (per pixel 10 f32: position, geometric normal,
/// view depth, object, triangle, flags = active + 2·compared).
pub fn write_light(dir: &Path, d: &LightDump) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let k = d.light;
    let gb = d.gbuffer;
    let points: Vec<String> = d
        .points
        .iter()
        .map(|p| format!("[{},{},{}]", p.x, p.y, p.z))
        .collect();
    let meta = format!(
        "{{\"width\":{},\"height\":{},\"words\":{},\"grid\":{},\"target\":[{},{}],\
         \"points\":[{}],\"note\":{:?}}}\n",
        gb.width,
        gb.height,
        d.words,
        d.grid,
        d.target.0,
        d.target.1,
        points.join(","),
        d.note
    );
    write(&dir.join(format!("light{k}-meta.json")), meta.as_bytes())?;
    let bits: Vec<u8> = d.bits.iter().flat_map(|w| w.to_le_bytes()).collect();
    write(&dir.join(format!("light{k}-bits.bin")), &bits)?;
    let amb: Vec<u8> = d.ambiguous.iter().flat_map(|w| w.to_le_bytes()).collect();
    write(&dir.join(format!("light{k}-ambiguous.bin")), &amb)?;
    let mut g = Vec::with_capacity(gb.len() * 40);
    for i in 0..gb.len() {
        let s = gb.sample(i);
        let flags = u8::from(d.active[i]) + 2 * u8::from(d.compared[i]);
        for v in [
            s.position.x,
            s.position.y,
            s.position.z,
            s.geo_normal.x,
            s.geo_normal.y,
            s.geo_normal.z,
            s.depth,
            s.object as f32,
            s.triangle as f32,
            f32::from(flags),
        ] {
            g.extend_from_slice(&v.to_le_bytes());
        }
    }
    write(&dir.join(format!("light{k}-gbuffer.bin")), &g)
}
