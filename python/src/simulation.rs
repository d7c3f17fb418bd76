//! `cellist.Simulation`: any scenario that `cellist run` runs, stepped from
//! Python. The session (model, observers, checkpoints) lives on a worker
//! thread of its own and is reached by messages, so that `run` can release the
//! GIL: two simulations in two Python threads run at once.

use crate::errors::{sim_error, value_error};
use crate::threads::pool;
use cellist_sim::checkpoint::encode;
use cellist_sim::observers::TrajectoryFrame;
use cellist_sim::session::{self, Session};
use cellist_sim::{Blowup, Scenario, SimError, SimResult};
use numpy::{AllowTypeChange, IntoPyArray, PyArrayLike2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Sender};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// What the worker thread owns: the session and its threads.
struct Engine {
    session: Box<dyn Session>,
    threads: cellist_sim::Threads,
}

/// The wall time a `run` call works between looks at Python's signals.
const SLICE: std::time::Duration = std::time::Duration::from_millis(200);

/// A request to the worker.
type Task = Box<dyn FnOnce(&mut Engine) + Send>;

/// What a scenario needs to be rebuilt (for pickling).
#[derive(Clone)]
struct Origin {
    text: String,
    origin: String,
    name: String,
    base_dir: PathBuf,
}

/// Simulation: a scenario of `cellist run` (md, pse, gravity, vortex) stepped from Python.
///
/// Build one with `Simulation.from_toml(path_or_text)` or
/// `Simulation.restart(checkpoint, scenario)`; `run(steps)` steps it with the
/// outputs of its scenario (thermo, dumps, fields, pictures, checkpoints) written
/// into its output folder, as `cellist run` writes them, except that the last
/// step of every `run` call counts as a last step (a thermo row, a checkpoint if
/// asked for). Arrays come back as read-only float64 numpy arrays in the user's
/// particle order: copies, which stay valid. Use it in a `with` block, or call
/// `close()`, to complete the files made at the end (plots, animations).
#[pyclass(module = "cellist", frozen)]
pub struct Simulation {
    tasks: Mutex<Option<Sender<Task>>>,
    worker: Mutex<Option<JoinHandle<SimResult>>>,
    scenario: Origin,
    out: PathBuf,
    threads: usize,
    model: String,
    dt: f64,
}

impl Simulation {
    /// Starts the worker thread, which opens the session (from `restart` if
    /// given) and then serves requests; returns once the session is open.
    fn start(
        py: Python<'_>,
        scenario: Origin,
        out: Option<PathBuf>,
        restart: Option<PathBuf>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let pool = pool(threads)?;
        let count = pool.count();
        let loaded = Scenario {
            base_dir: scenario.base_dir.clone(),
            ..Scenario::from_text(&scenario.text, &scenario.origin, &scenario.name)
        };
        let out = absolute(&out.unwrap_or_else(|| Path::new("out").join(&loaded.name)))?;
        let (tasks, inbox) = mpsc::channel::<Task>();
        let (ready_tx, ready) = mpsc::sync_channel(1);
        let dir = out.clone();
        let worker = std::thread::Builder::new()
            .name("cellist-simulation".into())
            .spawn(move || {
                let opened = session::open(&loaded, dir, restart.as_deref(), &pool);
                let (session, warnings) = match opened {
                    Ok(opened) => opened,
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return Ok(());
                    }
                };
                let facts = (
                    session.model().info().name.to_string(),
                    session.model().dt(),
                    warnings,
                );
                let _ = ready_tx.send(Ok(facts));
                let mut engine = Engine {
                    session,
                    threads: pool,
                };
                while let Ok(task) = inbox.recv() {
                    // a panic is a bug: the caller's reply channel closes and it
                    // raises RuntimeError; the worker goes on serving (close)
                    let _ = std::panic::catch_unwind(AssertUnwindSafe(|| task(&mut engine)));
                }
                // closed or dropped: complete the end-of-run files
                engine.session.finish_outputs()
            })
            .map_err(|e| {
                PyRuntimeError::new_err(format!("cannot start the simulation's thread: {e}"))
            })?;
        let opened = py.detach(move || ready.recv());
        let (model, dt, warnings) = match opened {
            Ok(Ok(facts)) => facts,
            Ok(Err(e)) => {
                let _ = worker.join();
                return Err(sim_error(py, e, None));
            }
            Err(_) => {
                let _ = worker.join();
                return Err(PyRuntimeError::new_err(
                    "the simulation's thread stopped while opening the scenario (a bug in cellist)",
                ));
            }
        };
        let warn = py.import("warnings")?;
        for w in warnings {
            warn.call_method1("warn", (w,))?;
        }
        Ok(Simulation {
            tasks: Mutex::new(Some(tasks)),
            worker: Mutex::new(Some(worker)),
            scenario,
            out,
            threads: count,
            model,
            dt,
        })
    }

    /// Runs `f` on the worker with the GIL released and returns its result.
    fn call<R: Send + 'static>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Engine) -> R + Send + 'static,
    ) -> PyResult<R> {
        let sender = self
            .tasks
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
            .ok_or_else(|| PyRuntimeError::new_err("the simulation is closed"))?;
        let (reply, answer) = mpsc::sync_channel(1);
        let task: Task = Box::new(move |engine| {
            let _ = reply.send(f(engine));
        });
        sender
            .send(task)
            .map_err(|_| PyRuntimeError::new_err("the simulation's thread has stopped"))?;
        py.detach(move || answer.recv()).map_err(|_| {
            PyRuntimeError::new_err(
                "the simulation's thread stopped during the call (a bug in cellist)",
            )
        })
    }

    /// The named arrays of the current state, converted to read-only numpy arrays.
    fn arrays<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let named = self.call(py, |e| e.session.arrays())?;
        let dict = PyDict::new(py);
        for (name, values, columns) in named {
            let rows = values.len() / columns.max(1);
            let array = values.into_pyarray(py);
            let array = if columns == 1 {
                array.into_any()
            } else {
                array.reshape([rows, columns])?.into_any()
            };
            array.getattr("flags")?.setattr("writeable", false)?;
            dict.set_item(name, array)?;
        }
        Ok(dict)
    }

    /// Replaces the array `name` by `values` (all finite), where the model allows it.
    fn set_array(
        &self,
        py: Python<'_>,
        name: &'static str,
        values: PyArrayLike2<'_, f64, AllowTypeChange>,
    ) -> PyResult<()> {
        let flat: Vec<f64> = values.as_array().iter().copied().collect();
        if let Some(bad) = flat.iter().position(|v| !v.is_finite()) {
            let columns = values.shape()[1].max(1);
            return Err(value_error(format!(
                "{name}[{}, {}] is {}: every value must be finite",
                bad / columns,
                bad % columns,
                flat[bad]
            )));
        }
        self.call(py, move |e| e.session.set_array(name, &flat, &e.threads))?
            .map_err(|err| sim_error(py, err, None))
    }

    /// Writes the current state's frame as `format` with `write(frame, step)`.
    fn write_frame(
        &self,
        py: Python<'_>,
        format: &'static str,
        write: impl FnOnce(&TrajectoryFrame, u64) -> SimResult + Send + 'static,
    ) -> PyResult<()> {
        self.call(py, move |e| {
            let step = e.session.step();
            TrajectoryFrame::required(e.session.model(), step, format)
                .and_then(|frame| write(&frame, step))
        })?
        .map_err(|err| sim_error(py, err, None))
    }

    /// One named array, or an AttributeError naming those the model has.
    fn array<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let all = self.arrays(py)?;
        match all.get_item(name)? {
            Some(a) => Ok(a),
            None => {
                let names: Vec<String> = all.keys().iter().map(|k| k.to_string()).collect();
                Err(pyo3::exceptions::PyAttributeError::new_err(format!(
                    "model '{}' has no array '{name}'; it has: {}",
                    self.model,
                    names.join(", ")
                )))
            }
        }
    }
}

/// Reads a scenario argument: a path (str or os.PathLike) to a TOML file, or
/// the TOML text itself (a str that is not an existing file and holds a newline
/// or an `=`).
fn scenario_of(arg: &Bound<'_, PyAny>) -> PyResult<Origin> {
    let text: Option<String> = arg.extract::<String>().ok();
    let is_text = text
        .as_deref()
        .is_some_and(|t| !Path::new(t).is_file() && (t.contains('\n') || t.contains('=')));
    if is_text {
        return Ok(Origin {
            text: text.unwrap_or_default(),
            origin: "the scenario text".into(),
            name: "scenario".into(),
            base_dir: absolute(Path::new(""))?,
        });
    }
    let path: PathBuf = arg.extract().map_err(|_| {
        value_error("the scenario must be a path (str or os.PathLike) or the TOML text (str)")
    })?;
    let loaded = Scenario::load(Some(&path), &[]).map_err(|e| value_error(e.to_string()))?;
    Ok(Origin {
        text: loaded.text,
        origin: loaded.origin,
        name: loaded.name,
        base_dir: absolute(&loaded.base_dir)?,
    })
}

/// `path` made absolute against the working folder, so that a pickled or
/// restarted simulation finds its inputs and outputs wherever it is rebuilt.
fn absolute(path: &Path) -> PyResult<PathBuf> {
    std::path::absolute(if path.as_os_str().is_empty() {
        Path::new(".")
    } else {
        path
    })
    .map_err(|e| value_error(format!("{}: {e}", path.display())))
}

#[pymethods]
impl Simulation {
    /// from_toml(path_or_text, threads=None, out=None)
    /// --
    ///
    /// The simulation of a scenario: a path to a TOML file, or the TOML text.
    /// threads: worker threads (default one per core; the results do not depend
    /// on it). out: the output folder (default out/<scenario name>).
    #[staticmethod]
    #[pyo3(signature = (path_or_text, threads=None, out=None))]
    fn from_toml(
        py: Python<'_>,
        path_or_text: &Bound<'_, PyAny>,
        threads: Option<usize>,
        out: Option<PathBuf>,
    ) -> PyResult<Self> {
        let scenario = scenario_of(path_or_text)?;
        Self::start(py, scenario, out, None, threads)
    }

    /// restart(checkpoint, scenario, threads=None, out=None)
    /// --
    ///
    /// The simulation of `scenario` (a path or TOML text) continued from the
    /// file `checkpoint`, checked against it as `cellist run --restart` does.
    #[staticmethod]
    #[pyo3(signature = (checkpoint, scenario, threads=None, out=None))]
    fn restart(
        py: Python<'_>,
        checkpoint: PathBuf,
        scenario: &Bound<'_, PyAny>,
        threads: Option<usize>,
        out: Option<PathBuf>,
    ) -> PyResult<Self> {
        let scenario = scenario_of(scenario)?;
        Self::start(py, scenario, out, Some(checkpoint), threads)
    }

    /// run(steps=None)
    /// --
    ///
    /// Runs `steps` more steps (default: on to the scenario's run.steps) with the
    /// GIL released. Ctrl-C stops it within a fraction of a second, at a step
    /// (KeyboardInterrupt). Raises cellist.BlowUp if the run blows up; the
    /// simulation is then back at its last good state.
    #[pyo3(signature = (steps=None))]
    fn run(&self, py: Python<'_>, steps: Option<u64>) -> PyResult<()> {
        let target = self.call(py, move |e| {
            let now = e.session.step();
            match steps {
                Some(n) => now.saturating_add(n),
                None => e.session.scenario_steps().max(now),
            }
        })?;
        // slices of about SLICE of wall time, so that Ctrl-C (a Python signal)
        // is seen between them; the run's last step is `target` throughout
        loop {
            let slice = self.call(py, move |e| {
                let started = std::time::Instant::now();
                while e.session.step() < target && started.elapsed() < SLICE {
                    let next = e.session.step() + 1;
                    if let Err(err) = e.session.advance(next, target, &e.threads) {
                        let blowup: Option<Blowup> = e.session.last_blowup().cloned();
                        return Err(Box::new((err, blowup)));
                    }
                }
                Ok(e.session.step() >= target)
            })?;
            match slice {
                Ok(true) => return Ok(()),
                Ok(false) => py.check_signals()?,
                Err(failure) => {
                    let (err, blowup) = *failure;
                    return Err(sim_error(py, err, blowup));
                }
            }
        }
    }

    /// The current step.
    #[getter]
    fn step(&self, py: Python<'_>) -> PyResult<u64> {
        self.call(py, |e| e.session.step())
    }

    /// The current time, step * dt.
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.step(py)? as f64 * self.dt)
    }

    /// The time step.
    #[getter]
    fn dt(&self) -> f64 {
        self.dt
    }

    /// The model's name ("md", "pse", "gravity", "vortex").
    #[getter]
    fn model(&self) -> &str {
        &self.model
    }

    /// The output folder.
    #[getter]
    fn out(&self) -> PathBuf {
        self.out.clone()
    }

    /// The worker threads.
    #[getter]
    fn threads(&self) -> usize {
        self.threads
    }

    /// Number of particles.
    fn __len__(&self, py: Python<'_>) -> PyResult<usize> {
        self.call(py, |e| e.session.model().len())
    }

    /// thermo()
    /// --
    ///
    /// The thermo columns at the current step, as a dict (the columns of the
    /// thermo table, `step` first).
    fn thermo<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (step, columns, values) = self.call(py, |e| {
            let step = e.session.step();
            let model = e.session.model();
            (
                step,
                model.info().thermo_columns.to_vec(),
                model.thermo(step),
            )
        })?;
        let dict = PyDict::new(py);
        dict.set_item("step", step)?;
        for (c, v) in columns.iter().zip(values) {
            dict.set_item(*c, v)?;
        }
        Ok(dict)
    }

    /// arrays()
    /// --
    ///
    /// Every per-particle array of the current state, by name, as read-only
    /// float64 numpy arrays in the user's particle order.
    #[pyo3(name = "arrays")]
    fn all_arrays<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.arrays(py)
    }

    /// Positions, (N, dim), wrapped into a periodic box as in the dumps.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.array(py, "positions")
    }

    /// Velocities, (N, dim).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.array(py, "velocities")
    }

    /// Forces, (N, dim) (md).
    #[getter]
    fn forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.array(py, "forces")
    }

    /// Particle strengths: pse, (N,), the field value times the particle volume;
    /// 3D vortex, (N, 3), the vector strengths alpha = omega h^3.
    #[getter]
    fn strengths<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.array(py, "strengths")
    }

    /// Circulations of the vortex particles (vortex).
    #[getter]
    fn circulations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.array(py, "circulations")
    }

    /// set_positions(values)
    /// --
    ///
    /// Replaces the positions, an (N, dim) array in the order of `positions`,
    /// where the model allows it (md); the model is set up anew from them (the
    /// checks of a new run, the neighbour list, the forces).
    fn set_positions(
        &self,
        py: Python<'_>,
        values: PyArrayLike2<'_, f64, AllowTypeChange>,
    ) -> PyResult<()> {
        self.set_array(py, "positions", values)
    }

    /// set_velocities(values)
    /// --
    ///
    /// Replaces the velocities, an (N, dim) array in the order of `velocities`,
    /// where the model allows it (md).
    fn set_velocities(
        &self,
        py: Python<'_>,
        values: PyArrayLike2<'_, f64, AllowTypeChange>,
    ) -> PyResult<()> {
        self.set_array(py, "velocities", values)
    }

    /// save_checkpoint(path)
    /// --
    ///
    /// Writes a checkpoint of the current state (atomically), which
    /// `Simulation.restart` and `cellist run --restart` continue bit for bit.
    fn save_checkpoint(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.call(py, move |e| e.session.save_checkpoint(&path))?
            .map_err(|err| sim_error(py, err, None))
    }

    /// write_gsd(path)
    /// --
    ///
    /// Appends the current state as one frame (HOOMD schema) to the GSD file at
    /// `path`, made if missing: what `[output] gsd = { every, file }` writes.
    fn write_gsd(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.write_frame(py, "GSD", move |frame, step| frame.append_gsd(&path, step))
    }

    /// write_vtp(path)
    /// --
    ///
    /// Writes the current state as one VTK PolyData file (points and their
    /// arrays) at `path`, for ParaView.
    fn write_vtp(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.write_frame(py, "VTK", move |frame, _| {
            frame
                .write_vtp(&path)
                .map_err(SimError::output(path.display().to_string()))
        })
    }

    /// close()
    /// --
    ///
    /// Completes the files made at the end of a run (plots, animations) and stops
    /// the simulation's thread. Further calls raise RuntimeError.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let sender = self.tasks.lock().unwrap_or_else(|e| e.into_inner()).take();
        drop(sender);
        let worker = self.worker.lock().unwrap_or_else(|e| e.into_inner()).take();
        let Some(worker) = worker else {
            return Ok(()); // already closed
        };
        match py.detach(move || worker.join()) {
            Ok(finished) => finished.map_err(|err| sim_error(py, err, None)),
            Err(_) => Err(PyRuntimeError::new_err(
                "the simulation's thread failed while completing its files (a bug in cellist)",
            )),
        }
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    fn __exit__(
        &self,
        py: Python<'_>,
        _kind: Option<&Bound<'_, PyAny>>,
        _value: Option<&Bound<'_, PyAny>>,
        _traceback: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        self.close(py)?;
        Ok(false)
    }

    /// Pickling: the scenario and the checkpoint bytes of the current state. The
    /// copy continues the run in a folder of its own beside this one's
    /// (`<out>-copy`, `<out>-copy2`, ...), with fresh output files.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let checkpoint = self
            .call(py, |e| e.session.checkpoint())?
            .map_err(|err| sim_error(py, err, None))?;
        let bytes = PyBytes::new(py, &encode(&checkpoint));
        let rebuild = py.import("cellist._cellist")?.getattr("_unpickle")?;
        let s = &self.scenario;
        let args = (
            s.text.clone(),
            s.origin.clone(),
            s.name.clone(),
            s.base_dir.clone(),
            self.out.clone(),
            self.threads,
            bytes,
        );
        PyTuple::new(py, [rebuild.into_any(), args.into_pyobject(py)?.into_any()])
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let step = self.step(py)?;
        Ok(format!(
            "<cellist.Simulation model={} step={step} out={}>",
            self.model,
            self.out.display()
        ))
    }
}

/// Rebuilds a pickled simulation from its scenario and checkpoint bytes.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn _unpickle(
    py: Python<'_>,
    text: String,
    origin: String,
    name: String,
    base_dir: PathBuf,
    out: PathBuf,
    threads: usize,
    checkpoint: &[u8],
) -> PyResult<Simulation> {
    let mut file = tempfile::NamedTempFile::new()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot make a temporary file: {e}")))?;
    std::io::Write::write_all(&mut file, checkpoint)
        .map_err(|e| PyRuntimeError::new_err(format!("cannot write a temporary file: {e}")))?;
    let scenario = Origin {
        text,
        origin,
        name,
        base_dir,
    };
    Simulation::start(
        py,
        scenario,
        Some(fresh_folder(&out)),
        Some(file.path().to_path_buf()),
        Some(threads),
    )
}

/// The first of `out-copy`, `out-copy2`, ... that does not exist: an unpickled
/// simulation writes there, so that it and the original never share a file.
fn fresh_folder(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    (1..)
        .map(|k| {
            let suffix = if k == 1 { String::new() } else { k.to_string() };
            out.with_file_name(format!("{name}-copy{suffix}"))
        })
        .find(|candidate| !candidate.exists())
        .expect("an unused folder name")
}
