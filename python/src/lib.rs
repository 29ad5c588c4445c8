//! `penumbra._penumbra`: the native module of the `penumbra` Python
//! package. It turns the adapter's plain data ([`api`]) into Python
//! objects and NumPy arrays; `penumbra/__init__.py` gives it its Python
//! face (keyword defaults, the `Render` class, docstrings).

mod api;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyNotImplementedError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

create_exception!(
    penumbra,
    SceneError,
    PyValueError,
    "A scene file (or TOML text) is invalid; the message names the file and line."
);

/// How often the calling thread looks for Ctrl-C while a render runs.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// The Python exception for a crate error: a file's problem is a
/// `SceneError` (a `ValueError`), a parameter's a `ValueError`, a path's
/// an `OSError`.
fn to_py_err(e: api::Error) -> PyErr {
    let (kind, message) = api::describe_error(&e);
    match kind {
        api::ErrorKind::File => SceneError::new_err(message),
        api::ErrorKind::Parameter => PyValueError::new_err(message),
        api::ErrorKind::Io => PyOSError::new_err(message),
        // Only a raised cancel flag gets here, and the interrupt that
        // raised it is re-raised instead (run_interruptible).
        api::ErrorKind::Cancelled => PyKeyboardInterrupt::new_err(message),
    }
}

/// A loaded scene (`penumbra.Scene` wraps it).
#[pyclass(frozen, module = "penumbra._penumbra")]
struct NativeScene {
    scene: api::Scene,
}

#[pymethods]
impl NativeScene {
    /// `(name, width, height, lights, triangles)`.
    fn summary(&self) -> (String, u32, u32, usize, usize) {
        let s = api::summary(&self.scene);
        (s.name, s.width, s.height, s.lights, s.triangles)
    }

    /// Renders; returns a dict of the pieces `penumbra.Render` is made of.
    #[pyo3(signature = (technique, samples, width, height, seed, aovs, threads, pattern, option_args, target_error, max_samples, max_time))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        technique: String,
        samples: u32,
        width: Option<u32>,
        height: Option<u32>,
        seed: u64,
        aovs: Vec<String>,
        threads: Option<usize>,
        pattern: Option<String>,
        option_args: Vec<String>,
        target_error: Option<f64>,
        max_samples: Option<u64>,
        max_time: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let request = api::Request {
            technique,
            samples,
            width,
            height,
            seed,
            aovs,
            threads,
            pattern,
            option_args,
            target_error,
            max_samples,
            max_time,
        };
        let cancel = api::Cancel::default();
        let data = run_interruptible(py, &cancel, || api::render(&self.scene, &request, &cancel))?
            .map_err(to_py_err)?;
        render_dict(py, data)
    }
}

/// Runs `work` on its own thread with the GIL released, while this thread
/// checks for signals every [`SIGNAL_POLL`]: on Ctrl-C (or any signal
/// handler that raises) it sets `cancel`, waits for `work` to return and
/// re-raises, so Python never sees a render still running behind it.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &api::Cancel,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (sender, mut receiver) = mpsc::channel();
        let worker = scope.spawn(move || {
            // The receiver outlives the worker (both are in this scope).
            let _ = sender.send(work());
        });
        let outcome = loop {
            // The receiver is not `Sync`: it moves into the GIL-free
            // closure and back out.
            let (back, received) = py.detach(move || {
                let received = receiver.recv_timeout(SIGNAL_POLL);
                (receiver, received)
            });
            receiver = back;
            match received {
                Ok(value) => break Ok(value),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if let Err(interrupt) = py.check_signals() {
                        cancel.cancel();
                        // Wait for the render to stop before re-raising.
                        let _ = py.detach(move || receiver.recv());
                        break Err(interrupt);
                    }
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    break Err(PyKeyboardInterrupt::new_err("the render thread stopped"))
                }
            }
        };
        if worker.join().is_err() {
            return Err(pyo3::exceptions::PyRuntimeError::new_err(
                "the render panicked (a bug in penumbra: please report it)",
            ));
        }
        outcome
    })
}

/// A float32 array of `shape` from row-major `values`.
fn array<'py>(py: Python<'py>, values: Vec<f32>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, values).reshape(shape)?.into_any())
}

/// The render's pieces as a dict: `width`, `height`, `radiance`
/// (H×W×3), `aovs` (name → (H×W×C, channel names)), `vcoef` (list of H×W),
/// `timings` (pass → seconds), `explain_json`, `warnings`.
fn render_dict(py: Python<'_>, data: api::RenderData) -> PyResult<Bound<'_, PyDict>> {
    let (h, w) = (data.height as usize, data.width as usize);
    let dict = PyDict::new(py);
    dict.set_item("width", data.width)?;
    dict.set_item("height", data.height)?;
    dict.set_item("radiance", array(py, data.radiance, &[h, w, 3])?)?;
    let aovs = PyDict::new(py);
    for layer in data.layers {
        let names: Vec<String> = layer.channels.iter().map(|(n, _)| n.clone()).collect();
        // Channels become the last axis (pixel-interleaved); the Python
        // side drops it for one-channel layers.
        let c = layer.channels.len();
        let mut values = vec![0.0f32; h * w * c];
        for (k, (_, channel)) in layer.channels.iter().enumerate() {
            for (i, v) in channel.iter().enumerate() {
                values[i * c + k] = *v;
            }
        }
        let value = array(py, values, &[h, w, c])?;
        aovs.set_item(&layer.name, (value, names))?;
    }
    dict.set_item("aovs", aovs)?;
    let vcoef = PyList::empty(py);
    for v in data.vcoef {
        vcoef.append(array(py, v, &[h, w])?)?;
    }
    dict.set_item("vcoef", vcoef)?;
    let timings = PyDict::new(py);
    for (name, seconds) in data.timings {
        timings.set_item(name, seconds)?;
    }
    dict.set_item("timings", timings)?;
    dict.set_item("explain_json", data.explain_json)?;
    dict.set_item("warnings", data.warnings)?;
    Ok(dict)
}

/// Loads a scene file.
#[pyfunction]
fn load_scene(py: Python<'_>, path: PathBuf) -> PyResult<NativeScene> {
    let scene = py.detach(|| api::load_scene(&path)).map_err(to_py_err)?;
    Ok(NativeScene { scene })
}

/// Parses scene TOML text; relative paths resolve from `base_dir`.
#[pyfunction]
fn scene_from_toml(py: Python<'_>, text: String, base_dir: PathBuf) -> PyResult<NativeScene> {
    let scene = py
        .detach(|| api::scene_from_toml(&text, &base_dir))
        .map_err(to_py_err)?;
    Ok(NativeScene { scene })
}

/// The crate's defaults of the Python signatures' arguments, as JSON text.
#[pyfunction]
fn defaults_json() -> String {
    api::defaults_json()
}

/// The technique registry as JSON text.
#[pyfunction]
fn techniques_json() -> String {
    api::techniques_json()
}

/// Runs a `compare` sweep; its records as JSON text.
#[pyfunction]
#[pyo3(signature = (scenes, techniques, samples, reference_samples, patterns, repeat, width, height, threads, seed, out, cache_dir, no_images, sweep_settings))]
#[allow(clippy::too_many_arguments)]
fn compare_json(
    py: Python<'_>,
    scenes: Vec<String>,
    techniques: Vec<String>,
    samples: Vec<u32>,
    reference_samples: u32,
    patterns: Vec<String>,
    repeat: u32,
    width: Option<u32>,
    height: Option<u32>,
    threads: Option<usize>,
    seed: u64,
    out: Option<String>,
    cache_dir: Option<String>,
    no_images: bool,
    sweep_settings: bool,
) -> PyResult<String> {
    let request = api::CompareRequest {
        scenes,
        techniques,
        samples,
        reference_samples,
        patterns,
        repeat,
        width,
        height,
        threads,
        seed,
        out,
        cache_dir,
        no_images,
        sweep_settings,
    };
    let cancel = api::Cancel::default();
    match run_interruptible(py, &cancel, || api::compare_json(&request, &cancel))? {
        Some(result) => result.map_err(to_py_err),
        None => Err(PyNotImplementedError::new_err(
            "penumbra.compare is not bound in this build",
        )),
    }
}

/// The native module.
#[pymodule]
fn _penumbra(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // NumPy's array API is looked up here, once: looked up on first use
    // (the first render's output arrays), a Ctrl-C landing in the look-up
    // (it runs NumPy's Python code) became a panic inside `numpy` instead
    // of the caller's KeyboardInterrupt. An error here is a Python error.
    numpy::get_array_module(m.py())?;
    let _ = PyArray1::<f32>::zeros(m.py(), 0, false);
    m.add_class::<NativeScene>()?;
    m.add_function(wrap_pyfunction!(load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(techniques_json, m)?)?;
    m.add_function(wrap_pyfunction!(defaults_json, m)?)?;
    m.add_function(wrap_pyfunction!(compare_json, m)?)?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("CANCEL_WIRED", api::CANCEL_WIRED)?;
    m.add("COMPARE_WIRED", api::COMPARE_WIRED)?;
    Ok(())
}
