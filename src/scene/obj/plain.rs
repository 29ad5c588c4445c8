//! The fast path for plain OBJ files: positions (`v x y z`) and triangles
//! of positive position indices (`f a b c`) only, besides comments and
//! smoothing groups, as scanners and subdividers write them. A 56 MB
//! file of 1.1M triangles took 1.8 s through the checking scan and tobj,
//! both single-threaded; here its chunks are parsed in parallel.
//!
//! **The same mesh as the general path, bit for bit.** Numbers are parsed
//! by the same `str::parse::<f32>` as tobj's; the vertices are renumbered
//! in order of first use by a face and only used ones kept, as tobj's
//! single-index export does; the model is tobj's (`unnamed_object`, no
//! material), so the rest of the load is shared. A file this path does
//! not take whole (any other statement, a face that is not a triangle of
//! plain indices, a non-finite or malformed number, a non-ASCII byte, an
//! index before its vertex, no face) returns `None` and takes the general
//! path, whose scan names the file and line of any error. `tests` holds
//! the two paths equal on generated files.

use rayon::prelude::*;

/// Bytes per parallel chunk (cut at the next line end).
const CHUNK: usize = 1 << 20;

/// What one chunk holds.
#[derive(Default)]
struct ChunkParse {
    positions: Vec<f32>,
    /// Position indices, 1-based as written.
    faces: Vec<u32>,
    /// The largest `index − vertices before the face in this chunk` over
    /// the chunk's faces: every index is defined before its face iff this
    /// is at most the vertices of the chunks before.
    ahead: i64,
}

/// `char::is_whitespace` on ASCII (what `split_whitespace`, hence tobj
/// and the scan, splits at): tab, line feed, vertical tab, form feed,
/// carriage return and space.
#[inline(always)]
fn is_space(b: u8) -> bool {
    matches!(b, b'\t'..=b'\r' | b' ')
}

/// Words of one chunk's lines, byte by byte (the chunk is ASCII, so any
/// byte offset is a character boundary of the `str`).
struct Words<'a> {
    text: &'a str,
    at: usize,
}

impl<'a> Words<'a> {
    /// The line's next word; `None` at the line's end (the line feed is
    /// left for [`Words::next_line`]).
    #[inline(always)]
    fn word(&mut self) -> Option<&'a str> {
        let b = self.text.as_bytes();
        while self.at < b.len() && b[self.at] != b'\n' && is_space(b[self.at]) {
            self.at += 1;
        }
        let start = self.at;
        while self.at < b.len() && !is_space(b[self.at]) {
            self.at += 1;
        }
        (self.at > start).then(|| &self.text[start..self.at])
    }

    /// Whether the line has no word left.
    #[inline(always)]
    fn line_ends(&mut self) -> bool {
        self.word().is_none()
    }

    /// Moves past the current line's end; false at the end of the text.
    #[inline(always)]
    fn next_line(&mut self) -> bool {
        let b = self.text.as_bytes();
        match b[self.at.min(b.len())..].iter().position(|&c| c == b'\n') {
            Some(i) => {
                self.at += i + 1;
                true
            }
            None => {
                self.at = b.len();
                false
            }
        }
    }
}

/// Parses one chunk (whole lines); `None` if any line is not plain.
fn parse_chunk(text: &[u8]) -> Option<ChunkParse> {
    if !text.is_ascii() {
        return None;
    }
    let text = std::str::from_utf8(text).ok()?;
    let mut out = ChunkParse {
        ahead: i64::MIN,
        ..ChunkParse::default()
    };
    let mut words = Words { text, at: 0 };
    loop {
        if let Some(keyword) = words.word() {
            match keyword {
                "v" => {
                    for _ in 0..3 {
                        let x: f32 = words.word()?.parse().ok()?;
                        if !x.is_finite() {
                            return None;
                        }
                        out.positions.push(x);
                    }
                    if !words.line_ends() {
                        return None;
                    }
                }
                "f" => {
                    let before = (out.positions.len() / 3) as i64;
                    for _ in 0..3 {
                        let word = words.word()?.as_bytes();
                        if word.len() > 9 || !word.iter().all(u8::is_ascii_digit) {
                            return None;
                        }
                        let index = word.iter().fold(0u32, |n, &d| n * 10 + u32::from(d - b'0'));
                        if index == 0 {
                            return None;
                        }
                        out.ahead = out.ahead.max(i64::from(index) - before);
                        out.faces.push(index);
                    }
                    if !words.line_ends() {
                        return None;
                    }
                }
                "s" => {}
                _ if keyword.starts_with('#') => {}
                _ => return None,
            }
        }
        if !words.next_line() {
            return Some(out);
        }
    }
}

/// The text cut into chunks of about [`CHUNK`] bytes at line ends.
fn chunks(text: &[u8]) -> Vec<&[u8]> {
    let mut out = Vec::with_capacity(text.len() / CHUNK + 1);
    let mut rest = text;
    while rest.len() > CHUNK {
        let cut = rest[CHUNK..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(rest.len(), |i| CHUNK + i + 1);
        let (head, tail) = rest.split_at(cut);
        out.push(head);
        rest = tail;
    }
    out.push(rest);
    out
}

/// The model tobj would make of `text` (triangulated, single index) when
/// the file is plain; `None` otherwise.
pub(super) fn parse(text: &str) -> Option<tobj::Model> {
    // Collecting into `Option` stops taking chunks at the first `None`:
    // a file that is not plain (a `vn` or `o` line near its start) costs
    // about a chunk per thread here before the general path.
    let mut parts: Vec<ChunkParse> = chunks(text.as_bytes())
        .into_par_iter()
        .map(parse_chunk)
        .collect::<Option<_>>()?;
    // Every index defined before its face (the scan's rule).
    let mut before = 0i64;
    for part in &parts {
        if part.ahead > before {
            return None;
        }
        before += (part.positions.len() / 3) as i64;
    }
    let faces: usize = parts.iter().map(|p| p.faces.len()).sum();
    if faces == 0 {
        return None;
    }
    // Each chunk's positions freed as they are moved on.
    let mut source = Vec::with_capacity(before as usize * 3);
    for part in &mut parts {
        source.append(&mut part.positions);
    }
    // tobj's single-index export: a vertex gets the next index at its
    // first use, and only used vertices are kept.
    let mut renumber = vec![u32::MAX; before as usize];
    let mut positions = Vec::with_capacity(source.len());
    let mut indices = Vec::with_capacity(faces);
    for &index in parts.iter().flat_map(|p| &p.faces) {
        let v = index as usize - 1;
        let slot = &mut renumber[v];
        if *slot == u32::MAX {
            *slot = (positions.len() / 3) as u32;
            positions.extend_from_slice(&source[3 * v..3 * v + 3]);
        }
        indices.push(*slot);
    }
    let mesh = tobj::Mesh {
        positions,
        indices,
        ..tobj::Mesh::default()
    };
    Some(tobj::Model::new(mesh, "unnamed_object".to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// tobj's model of `text`, as the general path loads it (the scan
    /// changes nothing in a plain file).
    fn tobj_model(text: &str) -> Option<tobj::Model> {
        let options = super::super::tobj_options();
        let (models, _) =
            tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| Ok(Default::default())).ok()?;
        let [model] = &models[..] else {
            return None;
        };
        Some(model.clone())
    }

    fn assert_same(a: &tobj::Model, b: &tobj::Model) {
        assert_eq!(a.name, b.name);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.mesh.positions), bits(&b.mesh.positions));
        assert_eq!(a.mesh.indices, b.mesh.indices);
        assert_eq!(a.mesh.material_id, b.mesh.material_id);
        assert_eq!(a.mesh.normals, b.mesh.normals);
        assert_eq!(a.mesh.texcoords, b.mesh.texcoords);
        assert_eq!(a.mesh.face_arities, b.mesh.face_arities);
        assert_eq!(a.mesh.vertex_color, b.mesh.vertex_color);
    }

    /// A random plain file: numbers in several spellings, comments,
    /// smoothing groups, blank lines, CRLF and odd whitespace, faces that
    /// reuse and skip vertices.
    fn plain_file(seed: u64, vertices: usize, faces: usize) -> String {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u32
        };
        let mut out = String::from("# generated\n\n");
        let spaces = [" ", "  ", "\t", " \t "];
        for _ in 0..vertices {
            let mut line = String::from("v");
            for _ in 0..3 {
                let x =
                    (next() as f32 / u32::MAX as f32 - 0.5) * 10f32.powi((next() % 12) as i32 - 6);
                let word = match next() % 5 {
                    0 => format!("{x}"),
                    1 => format!("{x:e}"),
                    2 => format!("{x:.3}"),
                    3 => format!("{:.9}", f64::from(x) * 1.000_000_1),
                    _ => format!("{}", x as f64),
                };
                line += spaces[(next() % 4) as usize];
                line += &word;
            }
            out += &line;
            out += if next() % 7 == 0 { " \r\n" } else { "\n" };
            if next() % 50 == 0 {
                out += "s off\n# a comment\n\n";
            }
        }
        for _ in 0..faces {
            let pick = |r: u32| 1 + r as usize % vertices;
            out += &format!("f {} {}\t{}\n", pick(next()), pick(next()), pick(next()));
        }
        out
    }

    #[test]
    fn plain_files_load_as_tobj_loads_them() {
        for seed in 0..40 {
            let (v, f) = (1 + seed as usize * 37 % 500, 1 + seed as usize * 53 % 900);
            let text = plain_file(seed, v.max(3), f);
            let ours = parse(&text).expect("a plain file");
            let theirs = tobj_model(&text).expect("tobj loads it");
            assert_same(&ours, &theirs);
        }
        // Several chunks: over 1 MiB of text.
        let text = plain_file(99, 40_000, 60_000);
        assert!(text.len() > 2 * CHUNK);
        assert_same(
            &parse(&text).expect("plain"),
            &tobj_model(&text).expect("tobj"),
        );
    }

    #[test]
    fn anything_else_takes_the_general_path() {
        let head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n";
        for tail in [
            "f 1 2 3 4\n",              // a quad: tobj triangulates it
            "f 1 2\n",                  // not a triangle
            "f 1/1 2/2 3/3\n",          // texture indices
            "f 1//1 2//1 3//1\n",       // normal indices
            "f -1 -2 -3\n",             // relative indices
            "f +1 2 3\n",               // a sign
            "f 0 1 2\n",                // index 0
            "f 1 2 5\n",                // index past the vertices
            "f 1 2 3\nv 1 2\n",         // two coordinates
            "f 1 2 3\nv 1 2 3 4\n",     // w
            "f 1 2 3\nv 1 2 3 1 1 1\n", // colour
            "f 1 2 3\nv 1 2 nan\n",     // non-finite
            "f 1 2 3\nv 1 2 1e39\n",    // overflows f32
            "f 1 2 3\nv 1 2 x\n",       // malformed
            "f 1 2 3\nvn 0 0 1\n",
            "f 1 2 3\nvt 0 0\n",
            "f 1 2 3\ng part\n",
            "f 1 2 3\no part\n",
            "f 1 2 3\nusemtl red\n",
            "mtllib a.mtl\nf 1 2 3\n",
            "f 1 2 3\nl 1 2\n",
            "f 1 2 3\n# \u{e9}\n", // non-ASCII
            "",                    // no face
        ] {
            assert!(parse(&format!("{head}{tail}")).is_none(), "{tail:?}");
        }
        // An index before its vertex, across chunks: the scan refuses it.
        let mut text = String::from("f 1 2 3\n");
        text += &"v 0 0 0\n".repeat(CHUNK / 4);
        assert!(parse(&text).is_none());
    }
}
