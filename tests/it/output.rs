//! PNG and EXR output: round trips, sRGB encoding, atomic replacement and
//! errors that name the output path.

use glam::Vec3;
use penumbra::internal::output::{
    check_output, read_image, srgb_encode_u8, write_atomically, write_exr, write_png, Layer,
    OutputSet,
};
use penumbra::Error;
use std::fs;
use std::path::{Path, PathBuf};

/// A fresh, empty directory for one test (removed at the end by `Drop`).
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("penumbra-output-{}-{}", std::process::id(), name));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    fn path(&self, file: &str) -> PathBuf {
        self.0.join(file)
    }

    /// The names of the files in the directory, sorted.
    fn listing(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Awkward float values that a lossy path would alter.
fn tricky(k: usize) -> f32 {
    const V: [f32; 8] = [
        0.0,
        -0.0,
        1.0e-40, // subnormal
        std::f32::consts::PI,
        -7.25e7,
        f32::MAX,
        f32::INFINITY,
        0.1,
    ];
    V[k % V.len()] * if k.is_multiple_of(3) { 1.0 } else { 0.999 }
}

#[test]
fn exr_round_trip_is_bit_identical_with_exact_channel_names() {
    let dir = Scratch::new("exr");
    let (w, h) = (7u32, 5u32);
    let n = (w * h) as usize;
    let radiance: Vec<Vec3> = (0..n)
        .map(|k| Vec3::new(tricky(k), tricky(k + 1), k as f32 / 3.0))
        .collect();
    let plane =
        |seed: usize| -> Vec<f32> { (0..n).map(|k| tricky(k * 7 + seed) + k as f32).collect() };
    let layers = vec![
        Layer {
            name: "depth".into(),
            channels: vec![("Z".into(), plane(1))],
        },
        Layer {
            name: "position".into(),
            channels: vec![
                ("X".into(), plane(2)),
                ("Y".into(), plane(3)),
                ("Z".into(), plane(4)),
            ],
        },
        Layer {
            name: "mask".into(),
            channels: vec![("Y".into(), plane(5))],
        },
        Layer {
            name: "vcoef".into(),
            channels: vec![("0".into(), plane(6)), ("1".into(), vec![f32::NAN; n])],
        },
    ];
    let path = dir.path("out.exr");
    write_exr(&path, w, h, &radiance, &layers).unwrap();
    assert_eq!(dir.listing(), ["out.exr"], "no temporary file left behind");

    let img = read_image(&path).unwrap();
    assert_eq!((img.width, img.height), (w, h));
    let mut names: Vec<&str> = img.channels.iter().map(|(n, _)| n.as_str()).collect();
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "B",
            "G",
            "R",
            "depth.Z",
            "mask.Y",
            "position.X",
            "position.Y",
            "position.Z",
            "vcoef.0",
            "vcoef.1"
        ]
    );
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    let r: Vec<f32> = radiance.iter().map(|c| c.x).collect();
    let g: Vec<f32> = radiance.iter().map(|c| c.y).collect();
    let b: Vec<f32> = radiance.iter().map(|c| c.z).collect();
    assert_eq!(bits(img.channel("R").unwrap()), bits(&r));
    assert_eq!(bits(img.channel("G").unwrap()), bits(&g));
    assert_eq!(bits(img.channel("B").unwrap()), bits(&b));
    for layer in &layers {
        for (name, values) in &layer.channels {
            let full = format!("{}.{}", layer.name, name);
            assert_eq!(bits(img.channel(&full).unwrap()), bits(values), "{full}");
        }
    }
    // Row 0 is the top: pixel (x, y) is value y * w + x.
    assert_eq!(
        img.channel("B").unwrap()[(w + 2) as usize],
        (w + 2) as f32 / 3.0
    );
}

#[test]
fn exr_rejects_bad_layers_naming_the_path() {
    let dir = Scratch::new("exr-bad");
    let path = dir.path("bad.exr");
    let rad = vec![Vec3::ZERO; 4];
    let short = [Layer {
        name: "depth".into(),
        channels: vec![("Z".into(), vec![0.0; 3])],
    }];
    let e = write_exr(&path, 2, 2, &rad, &short).unwrap_err();
    assert!(
        e.to_string().contains("bad.exr") && e.to_string().contains("depth.Z"),
        "{e}"
    );
    let twice = [Layer {
        name: "depth".into(),
        channels: vec![("Z".into(), vec![0.0; 4]); 2],
    }];
    let e = write_exr(&path, 2, 2, &rad, &twice).unwrap_err();
    assert!(e.to_string().contains("twice"), "{e}");
    let e = write_exr(&path, 3, 2, &rad, &[]).unwrap_err();
    assert!(e.to_string().contains("bad.exr"), "{e}");
    assert!(
        dir.listing().is_empty(),
        "nothing written: {:?}",
        dir.listing()
    );
}

#[test]
fn srgb_encoding_of_known_values() {
    assert_eq!(srgb_encode_u8(0.0), 0);
    assert_eq!(srgb_encode_u8(1.0), 255);
    assert_eq!(srgb_encode_u8(0.5), 188);
    assert_eq!(srgb_encode_u8(0.2), 124);
    assert_eq!(srgb_encode_u8(0.0031308), 10); // end of the linear segment: 0.0404 · 255
    assert_eq!(srgb_encode_u8(0.001), 3); // linear segment: 12.92 · 0.001 · 255 = 3.29
    assert_eq!(srgb_encode_u8(7.5), 255);
    assert_eq!(srgb_encode_u8(f32::INFINITY), 255);
    assert_eq!(srgb_encode_u8(-1.0), 0);
    assert_eq!(srgb_encode_u8(f32::NEG_INFINITY), 0);
    assert_eq!(srgb_encode_u8(f32::NAN), 0);
    // Monotone over the whole range.
    let mut last = 0;
    for k in 0..=10_000 {
        let c = srgb_encode_u8(k as f32 / 10_000.0);
        assert!(c >= last);
        last = c;
    }
}

#[test]
fn png_holds_the_encoded_bytes_and_decodes_to_linear() {
    let dir = Scratch::new("png");
    let path = dir.path("img.png");
    // 3 × 2, row 0 at the top.
    let radiance = vec![
        Vec3::new(0.0, 1.0, 0.5),
        Vec3::new(2.0, f32::NAN, -3.0),
        Vec3::new(0.2, 0.001, f32::INFINITY),
        Vec3::splat(0.5),
        Vec3::ZERO,
        Vec3::ONE,
    ];
    write_png(&path, 3, 2, &radiance).unwrap();
    assert_eq!(dir.listing(), ["img.png"]);

    // The raw 8-bit codes, through the image crate.
    let raw = image::open(&path).unwrap();
    assert_eq!(raw.color(), image::ColorType::Rgb8);
    assert_eq!((raw.width(), raw.height()), (3, 2));
    let bytes = raw.to_rgb8().into_raw();
    assert_eq!(
        bytes,
        [0, 255, 188, 255, 0, 0, 124, 3, 255, 188, 188, 188, 0, 0, 0, 255, 255, 255]
    );

    // read_image decodes sRGB back to linear: 188 → 0.5029 (the code's
    // centre), exact at 0 and 1.
    let img = read_image(&path).unwrap();
    assert_eq!((img.width, img.height), (3, 2));
    let names: Vec<&str> = img.channels.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["R", "G", "B"]);
    let r = img.channel("R").unwrap();
    assert_eq!(r[0], 0.0);
    assert_eq!(r[1], 1.0);
    assert!((r[3] - 0.5).abs() < 0.004, "{}", r[3]);
    assert!((img.channel("B").unwrap()[0] - 0.5).abs() < 0.004);
}

#[test]
fn atomic_write_replaces_only_on_success() {
    let dir = Scratch::new("atomic");
    let path = dir.path("result.png");

    // Success: the new content, nothing else in the directory.
    write_atomically(&path, |tmp| {
        assert_eq!(tmp.parent(), path.parent(), "temp file beside the target");
        assert!(tmp
            .to_string_lossy()
            .contains(&std::process::id().to_string()));
        fs::write(tmp, b"first").map_err(|e| Error::io(tmp, e))
    })
    .unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"first");
    assert_eq!(dir.listing(), ["result.png"]);

    // A writer that writes part of a file and then fails: the old file is
    // untouched, the temp file is gone, and the error names the target.
    let e = write_atomically(&path, |tmp| {
        fs::write(tmp, b"half").map_err(|e| Error::io(tmp, e))?;
        Err(Error::io(tmp, std::io::Error::other("disk on fire")))
    })
    .unwrap_err();
    assert_eq!(fs::read(&path).unwrap(), b"first");
    assert_eq!(dir.listing(), ["result.png"]);
    let msg = e.to_string();
    assert!(
        msg.contains("result.png") && msg.contains("disk on fire"),
        "{msg}"
    );
    assert!(
        !msg.contains(".tmp"),
        "the temp name is an implementation detail: {msg}"
    );

    // A real writer over an existing file.
    write_png(&path, 1, 1, &[Vec3::ONE]).unwrap();
    assert_eq!(dir.listing(), ["result.png"]);
    assert_eq!(read_image(&path).unwrap().channel("G").unwrap(), [1.0]);
}

#[test]
fn unwritable_paths_give_clear_errors() {
    let dir = Scratch::new("unwritable");
    // Parent directory missing.
    let missing = dir.path("no/such/dir/out.png");
    let e = write_png(&missing, 1, 1, &[Vec3::ONE]).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    assert!(
        msg.contains("no/such/dir/out.png") && msg.contains("does not exist")
            || msg.contains("No such file"),
        "{msg}"
    );

    // Parent is a regular file (works even as root, unlike permissions).
    let file = dir.path("plain");
    fs::write(&file, b"x").unwrap();
    let under_file = file.join("out.exr");
    let e = write_exr(&under_file, 1, 1, &[Vec3::ONE], &[]).unwrap_err();
    assert!(e.to_string().contains("plain/out.exr"), "{e}");

    // The target is a directory: the rename fails, the temp file is removed.
    let sub = dir.path("sub");
    fs::create_dir(&sub).unwrap();
    fs::write(sub.join("keep"), b"k").unwrap();
    let e = write_png(&sub, 1, 1, &[Vec3::ONE]).unwrap_err();
    assert!(e.to_string().contains("sub"), "{e}");
    assert_eq!(dir.listing(), ["plain", "sub"]);

    // A path with no file name.
    let e = write_png(Path::new("/"), 1, 1, &[Vec3::ONE]).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");

    // Reading: missing file, and a file that is neither format.
    let e = read_image(&dir.path("absent.exr")).unwrap_err();
    assert!(e.to_string().contains("absent.exr"), "{e}");
    let e = read_image(&file).unwrap_err();
    assert!(e.to_string().contains("not a PNG or an OpenEXR"), "{e}");
}

/// A tiny valid image for the output tests.
fn one_pixel() -> [Vec3; 1] {
    [Vec3::new(0.25, 0.5, 1.0)]
}

fn is_png(path: &Path) -> bool {
    fs::read(path).is_ok_and(|b| b.starts_with(b"\x89PNG"))
}

/// Issue 19.1: a symlink at the output path is followed: the file it
/// points to is replaced (through a chain of links, and a dangling link's
/// target is created), and the links stay links.
#[cfg(unix)]
#[test]
fn symlinks_are_followed_to_their_target() {
    use std::os::unix::fs::{symlink, PermissionsExt};
    let dir = Scratch::new("symlink");
    let real = dir.path("real.png");
    fs::write(&real, b"old").unwrap();
    fs::set_permissions(&real, fs::Permissions::from_mode(0o640)).unwrap();
    symlink("real.png", dir.path("link.png")).unwrap();
    symlink(dir.path("link.png"), dir.path("link2.png")).unwrap();
    write_png(&dir.path("link2.png"), 1, 1, &one_pixel()).unwrap();
    assert!(is_png(&real), "the link's target gets the image");
    for link in ["link.png", "link2.png"] {
        let m = fs::symlink_metadata(dir.path(link)).unwrap();
        assert!(m.file_type().is_symlink(), "{link} is still a link");
    }
    let mode = fs::metadata(&real).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640, "the replaced file keeps its permissions");
    // A dangling link: its target is created, in the target's directory.
    fs::create_dir(dir.path("sub")).unwrap();
    symlink("sub/new.exr", dir.path("dangling.exr")).unwrap();
    write_exr(&dir.path("dangling.exr"), 1, 1, &one_pixel(), &[]).unwrap();
    assert_eq!(read_image(&dir.path("sub/new.exr")).unwrap().width, 1);
    assert!(fs::symlink_metadata(dir.path("dangling.exr"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(
        dir.listing(),
        ["dangling.exr", "link.png", "link2.png", "real.png", "sub"],
        "no temporary files left"
    );
    // A loop of links is an error, not a hang.
    symlink("loop-b", dir.path("loop-a")).unwrap();
    symlink("loop-a", dir.path("loop-b")).unwrap();
    let e = write_png(&dir.path("loop-a"), 1, 1, &one_pixel()).unwrap_err();
    assert!(e.to_string().contains("loop-a"), "{e}");
}

/// Issue 19.1: a FIFO is written in place (its reader gets the image) and
/// stays a FIFO.
#[cfg(unix)]
#[test]
fn fifo_is_written_in_place() {
    use std::os::unix::fs::FileTypeExt;
    let dir = Scratch::new("fifo");
    let fifo = dir.path("pipe.png");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("mkfifo unavailable: skipped");
        return;
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || fs::read(fifo).unwrap())
    };
    write_png(&fifo, 1, 1, &one_pixel()).unwrap();
    let got = reader.join().unwrap();
    assert!(
        got.starts_with(b"\x89PNG"),
        "the reader got {} bytes",
        got.len()
    );
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    assert_eq!(dir.listing(), ["pipe.png"]);
}

/// Issue 19.1: character devices are written in place (`/dev/null`
/// stays a device; `/dev/full` reports its error instead of being
/// replaced by a regular file); sockets and directories are refused with
/// their kind named; a file in a directory that accepts no new files
/// (`/proc`) says so rather than "No such file or directory".
#[cfg(unix)]
#[test]
fn special_files_are_never_replaced() {
    use std::os::unix::fs::FileTypeExt;
    if Path::new("/dev/null").exists() {
        write_png(Path::new("/dev/null"), 1, 1, &one_pixel()).unwrap();
        write_exr(Path::new("/dev/null"), 1, 1, &one_pixel(), &[]).unwrap();
        assert!(fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
    }
    if Path::new("/dev/full").exists() {
        let e = write_exr(Path::new("/dev/full"), 1, 1, &one_pixel(), &[]).unwrap_err();
        assert!(e.to_string().contains("/dev/full"), "{e}");
        assert!(fs::metadata("/dev/full")
            .unwrap()
            .file_type()
            .is_char_device());
    }
    let dir = Scratch::new("special");
    let socket = dir.path("sock.png");
    let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    let e = write_png(&socket, 1, 1, &one_pixel()).unwrap_err();
    assert!(e.to_string().contains("is a socket"), "{e}");
    assert!(fs::symlink_metadata(&socket)
        .unwrap()
        .file_type()
        .is_socket());
    let e = write_png(&dir.0, 1, 1, &one_pixel()).unwrap_err();
    assert!(e.to_string().contains("is a directory"), "{e}");
    if Path::new("/proc/version").exists() {
        let before = fs::read("/proc/version").unwrap();
        let e = write_png(Path::new("/proc/version"), 1, 1, &one_pixel()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("/proc/version"), "{msg}");
        assert!(!msg.contains("No such file"), "{msg}");
        assert!(msg.contains("does not accept new files"), "{msg}");
        assert_eq!(fs::read("/proc/version").unwrap(), before);
    }
}

/// Issue 19.2: an `OutputSet` moves its outputs into place only when all
/// were written; a failed or abandoned set leaves every path as it was
/// and no temporary file behind.
#[test]
fn output_set_commits_all_or_none() {
    let dir = Scratch::new("set");
    let png = dir.path("o.png");
    let exr = dir.path("o.exr");

    // The second output fails: the first is not written.
    let mut set = OutputSet::new();
    set.png(&png, 1, 1, &one_pixel()).unwrap();
    let e = set
        .exr(&dir.path("missing-dir/x.exr"), 1, 1, &one_pixel(), &[])
        .unwrap_err();
    assert!(e.to_string().contains("does not exist"), "{e}");
    drop(set);
    assert!(dir.listing().is_empty(), "{:?}", dir.listing());

    // Existing outputs keep their content when a later one fails.
    fs::write(&png, b"old").unwrap();
    let mut set = OutputSet::new();
    set.png(&png, 1, 1, &one_pixel()).unwrap();
    let bad = vec![Layer {
        name: "depth".into(),
        channels: vec![("Z".into(), vec![0.0; 2])], // wrong length
    }];
    assert!(set.exr(&exr, 1, 1, &one_pixel(), &bad).is_err());
    drop(set);
    assert_eq!(fs::read(&png).unwrap(), b"old");
    assert_eq!(dir.listing(), ["o.png"]);

    // Staged but not committed: nothing visible yet; commit: both.
    let mut set = OutputSet::new();
    set.png(&png, 1, 1, &one_pixel()).unwrap();
    set.exr(&exr, 1, 1, &one_pixel(), &[]).unwrap();
    assert_eq!(fs::read(&png).unwrap(), b"old");
    assert!(!exr.exists());
    set.commit().unwrap();
    assert!(is_png(&png));
    assert_eq!(read_image(&exr).unwrap().channel("G").unwrap(), [0.5]);
    assert_eq!(dir.listing(), ["o.exr", "o.png"]);

    // The same file twice in one set is an error, not a silent overwrite.
    let mut set = OutputSet::new();
    set.png(&png, 1, 1, &one_pixel()).unwrap();
    let e = set.exr(&png, 1, 1, &one_pixel(), &[]).unwrap_err();
    assert!(e.to_string().contains("same file"), "{e}");

    // check_output: what staging would refuse, without writing.
    check_output(&dir.path("new.png")).unwrap();
    assert!(check_output(&dir.path("missing-dir/new.png")).is_err());
    assert!(check_output(&dir.0).is_err());
    assert!(!dir.path("new.png").exists());
}
