//! `sweep --slurm`: sbatch scripts for a sharded `compare` (or a banded
//! `render`): one job array (one task per shard or band, `--array=1-N%K`)
//! and a merge job that depends on it (`afterok`), optionally a
//! references job the array depends on. Slurm distributes the work; we
//! only write the scripts and, with `--submit`, call `sbatch`.
//!
//! Layout under `--out DIR` (which must be on a filesystem every node
//! mounts at the same path): `DIR/slurm/*.sbatch` (the scripts),
//! `DIR/logs/` (one log per task: `NAME_%A_%a.out`, the merge's
//! `NAME-merge_%j.out`), `DIR/shards/` (every compare shard's partial result
//! `shard-I-of-N.json`) or `DIR/tiles/I.part` (band I), and the merged results in
//! `DIR` itself (compare) or `DIR/render.png` + `DIR/render.exr`.

use crate::error::{Error, Result};
use crate::output::{write_atomically, write_stdout};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The Slurm settings of every job the sweep writes.
#[derive(Debug, Clone, clap::Args)]
pub struct SlurmArgs {
    /// Job name (`--job-name`; the merge job gets `-merge`, the references
    /// job `-refs` appended).
    #[arg(long, default_value = "penumbra")]
    pub job_name: String,
    /// Partition (`--partition`; default: the cluster's).
    #[arg(long)]
    pub partition: Option<String>,
    /// Time limit of each task (`--time`, e.g. 30, 2:00:00, 1-00:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// CPUs per task (`--cpus-per-task`); penumbra runs that many threads
    /// unless the forwarded arguments set `--threads`.
    #[arg(long, default_value_t = 1)]
    pub cpus_per_task: u32,
    /// Memory per node (`--mem`, e.g. 4G).
    #[arg(long)]
    pub mem: Option<String>,
    /// Account to charge (`--account`).
    #[arg(long)]
    pub account: Option<String>,
    /// Quality of service (`--qos`).
    #[arg(long)]
    pub qos: Option<String>,
    /// Node features required (`--constraint`).
    #[arg(long)]
    pub constraint: Option<String>,
    /// At most this many array tasks at once (`--array=1-N%K`).
    #[arg(long, value_name = "K")]
    pub throttle: Option<u32>,
    /// Time limit of the merge job (default: --time).
    #[arg(long)]
    pub merge_time: Option<String>,
    /// Memory of the merge job (default: --mem).
    #[arg(long)]
    pub merge_mem: Option<String>,
    /// Extra sbatch option for every job, as it would be typed
    /// (`--sbatch-arg=--mail-type=END`); repeatable.
    #[arg(long, value_name = "OPTION", allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// A shell line every job runs before penumbra (e.g. `module load
    /// gcc`); repeatable.
    #[arg(long, value_name = "LINE")]
    pub setup: Vec<String>,
    /// Log directory (default: OUT/logs).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
}

/// `penumbra sweep`: its command line.
#[derive(Debug, Clone, clap::Args)]
pub struct SweepArgs {
    /// Write Slurm batch scripts (the only scheduler supported).
    #[arg(long = "slurm", required = true)]
    pub use_slurm: bool,
    /// Compare shards: one array task each (`compare --shard I/N`).
    #[arg(long, value_name = "N", conflicts_with = "render")]
    pub shards: Option<u32>,
    /// Render this scene in bands instead (`render --tiles I/N`).
    #[arg(long, value_name = "SCENE", requires = "tiles")]
    pub render: Option<PathBuf>,
    /// Bands of the --render image: one array task each.
    #[arg(long, value_name = "N", requires = "render")]
    pub tiles: Option<u32>,
    /// Output directory on the shared filesystem (scripts, logs, partial
    /// and merged results).
    #[arg(long)]
    pub out: PathBuf,
    /// Also a job computing the references first (`compare
    /// --references-only`), which the array depends on; without it the
    /// first shard that needs a reference computes it under the cache lock.
    #[arg(long, conflicts_with = "render")]
    pub references_job: bool,
    /// Submit the scripts with sbatch (prints the job ids).
    #[arg(long)]
    pub submit: bool,
    /// Print the scripts; write and submit nothing.
    #[arg(long, conflicts_with = "submit")]
    pub dry_run: bool,
    /// The penumbra binary the jobs run (default: this one, by its
    /// absolute path; it must be visible to every node).
    #[arg(long)]
    pub penumbra: Option<PathBuf>,
    /// The sbatch command.
    #[arg(long, default_value = "sbatch")]
    pub sbatch: PathBuf,
    /// The job's resources and Slurm options.
    #[command(flatten)]
    pub job: SlurmArgs,
    /// The arguments of `compare` (scenes, --techniques, ...) or `render`
    /// (--technique, --samples, ...) every task runs with, after `--`.
    #[arg(last = true)]
    pub args: Vec<String>,
}

/// What the array tasks do.
#[derive(Debug, Clone, PartialEq)]
pub enum Work {
    /// `compare ARGS --shard I/N`, then `compare --merge`.
    Compare {
        /// Forwarded compare arguments.
        args: Vec<String>,
        /// Whether a references job runs first.
        references_job: bool,
    },
    /// `render SCENE ARGS --tiles I/N`, then `merge-tiles`.
    Render {
        /// The scene.
        scene: PathBuf,
        /// Forwarded render arguments.
        args: Vec<String>,
    },
}

/// A sweep's scripts, and where they go.
#[derive(Debug, Clone, PartialEq)]
pub struct Scripts {
    /// `(path, text)` of the references job, if any.
    pub references: Option<(PathBuf, String)>,
    /// The array job.
    pub array: (PathBuf, String),
    /// The merge job.
    pub merge: (PathBuf, String),
}

/// Quotes `s` as one word of a POSIX shell (bare when nothing needs
/// quoting), as `shlex` does; a NUL byte, which no shell word can hold,
/// is an error.
pub fn shell_quote(s: &str) -> Result<String> {
    shlex::try_quote(s).map(String::from).map_err(|_| {
        Error::param(
            "sweep",
            format!("{s:?} holds a NUL byte, which a script cannot pass on"),
        )
    })
}

fn quote_path(p: &Path) -> Result<String> {
    shell_quote(&p.display().to_string())
}

/// Refuses a value that would not stay on its own line of a script: a
/// newline in `--partition` would start a new `#SBATCH` directive (or a
/// shell command), other control characters are never meant. `option`
/// names the option.
fn check_one_line(option: &str, value: &str) -> Result<()> {
    if let Some(c) = value.chars().find(|c| c.is_control()) {
        return Err(Error::param(
            option,
            format!(
                "{value:?} holds the control character {c:?}; a script line \
                 takes no newlines or control characters"
            ),
        ));
    }
    Ok(())
}

/// One sbatch option from the user must be a single line starting `-`.
fn check_sbatch_arg(a: &str) -> Result<()> {
    check_one_line("--sbatch-arg", a)?;
    if !a.starts_with('-') {
        return Err(Error::param(
            "--sbatch-arg",
            format!("`{a}` is not one sbatch option (such as --mail-type=END)"),
        ));
    }
    Ok(())
}

/// A job's `#SBATCH` header.
fn header(
    slurm: &SlurmArgs,
    name: &str,
    log: &Path,
    time: Option<&str>,
    mem: Option<&str>,
    chdir: &Path,
) -> Result<String> {
    let mut h = String::from("#!/bin/bash\n");
    let mut line = |opt: String| {
        h.push_str("#SBATCH ");
        h.push_str(&opt);
        h.push('\n');
    };
    line(format!("--job-name={}", shell_quote(name)?));
    line(format!("--output={}", quote_path(log)?));
    line(format!("--chdir={}", quote_path(chdir)?));
    line("--nodes=1".into());
    line("--ntasks=1".into());
    line(format!("--cpus-per-task={}", slurm.cpus_per_task));
    for (opt, v) in [
        ("partition", slurm.partition.as_deref()),
        ("time", time),
        ("mem", mem),
        ("account", slurm.account.as_deref()),
        ("qos", slurm.qos.as_deref()),
        ("constraint", slurm.constraint.as_deref()),
    ] {
        if let Some(v) = v {
            line(format!("--{opt}={}", shell_quote(v)?));
        }
    }
    for a in &slurm.sbatch_arg {
        line(a.clone());
    }
    Ok(h)
}

/// The shell lines every job starts with after its header.
fn prologue(slurm: &SlurmArgs) -> String {
    let mut s = String::from("set -euo pipefail\n");
    for l in &slurm.setup {
        s.push_str(l);
        s.push('\n');
    }
    s.push_str(
        "echo \"penumbra job ${SLURM_JOB_ID:-?} task ${SLURM_ARRAY_TASK_ID:-} on $(hostname)\"\n",
    );
    s
}

/// `penumbra` and `words` as one quoted shell command line.
fn command(penumbra: &Path, words: &[String]) -> Result<String> {
    let mut s = quote_path(penumbra)?;
    for w in words {
        s.push(' ');
        s.push_str(&shell_quote(w)?);
    }
    Ok(s)
}

/// `--threads "$SLURM_CPUS_PER_TASK"` unless the arguments set it.
fn threads(args: &[String]) -> &'static str {
    if args
        .iter()
        .any(|a| a == "--threads" || a.starts_with("--threads="))
    {
        ""
    } else {
        " --threads \"${SLURM_CPUS_PER_TASK:-1}\""
    }
}

/// The scripts of a sweep of `tasks` array tasks writing under `out`
/// (absolute), run from `chdir` with the binary `penumbra`.
pub fn scripts(
    work: &Work,
    tasks: u32,
    out: &Path,
    chdir: &Path,
    penumbra: &Path,
    slurm: &SlurmArgs,
) -> Result<Scripts> {
    check_settings(tasks, out, chdir, penumbra, slurm)?;
    let jobs = Jobs {
        slurm,
        tasks,
        out,
        chdir,
        penumbra,
        logs: slurm.log_dir.clone().unwrap_or_else(|| out.join("logs")),
    };
    let mut array = jobs.array_start()?;
    let mut merge = jobs.merge_start()?;
    let references = match work {
        Work::Compare {
            args,
            references_job,
        } => jobs.compare_commands(args, *references_job, &mut array, &mut merge)?,
        Work::Render { scene, args } => {
            jobs.render_commands(scene, args, &mut array, &mut merge)?;
            None
        }
    };
    let dir = out.join("slurm");
    Ok(Scripts {
        references: references.map(|text| (dir.join("references.sbatch"), text)),
        array: (dir.join("array.sbatch"), array),
        merge: (dir.join("merge.sbatch"), merge),
    })
}

/// Refuses settings that Slurm would reject or that would not stay on
/// their line of a script, before any script is written.
fn check_settings(
    tasks: u32,
    out: &Path,
    chdir: &Path,
    penumbra: &Path,
    slurm: &SlurmArgs,
) -> Result<()> {
    if tasks == 0 {
        return Err(Error::param("--shards/--tiles", "at least 1 task"));
    }
    if slurm.cpus_per_task == 0 {
        return Err(Error::param("--cpus-per-task", "at least 1"));
    }
    if slurm.throttle == Some(0) {
        return Err(Error::param("--throttle", "at least 1 task at once"));
    }
    for a in &slurm.sbatch_arg {
        check_sbatch_arg(a)?;
    }
    for (option, value) in [
        ("--job-name", Some(slurm.job_name.as_str())),
        ("--partition", slurm.partition.as_deref()),
        ("--time", slurm.time.as_deref()),
        ("--mem", slurm.mem.as_deref()),
        ("--account", slurm.account.as_deref()),
        ("--qos", slurm.qos.as_deref()),
        ("--constraint", slurm.constraint.as_deref()),
        ("--merge-time", slurm.merge_time.as_deref()),
        ("--merge-mem", slurm.merge_mem.as_deref()),
    ] {
        if let Some(v) = value {
            check_one_line(option, v)?;
        }
    }
    for line in &slurm.setup {
        check_one_line("--setup", line)?;
    }
    // Paths on #SBATCH lines are quoted, but a newline inside quotes
    // still ends the directive.
    let logs_text = slurm.log_dir.as_ref().map(|p| p.display().to_string());
    for (option, path) in [
        ("--out", Some(out.display().to_string())),
        ("--log-dir", logs_text),
        ("the working directory", Some(chdir.display().to_string())),
        ("--penumbra", Some(penumbra.display().to_string())),
    ] {
        if let Some(p) = path {
            check_one_line(option, &p)?;
        }
    }
    if slurm.job_name.is_empty() || slurm.job_name.contains(['\n', '/']) {
        return Err(Error::param(
            "--job-name",
            "a non-empty name without / or newlines",
        ));
    }
    Ok(())
}

/// What every job script of one (checked) sweep shares.
struct Jobs<'a> {
    slurm: &'a SlurmArgs,
    /// Array tasks (shards or bands).
    tasks: u32,
    /// The sweep's output directory (absolute).
    out: &'a Path,
    /// Where the jobs run.
    chdir: &'a Path,
    /// The binary the jobs run.
    penumbra: &'a Path,
    /// Where the jobs' logs go.
    logs: PathBuf,
}

/// The array task's index in a script line.
const TASK: &str = "\"$SLURM_ARRAY_TASK_ID\"";

impl Jobs<'_> {
    /// The array job up to its command: header, `--array` and prologue.
    fn array_start(&self) -> Result<String> {
        let (slurm, name, tasks) = (self.slurm, &self.slurm.job_name, self.tasks);
        let array_range = match slurm.throttle {
            Some(k) => format!("1-{tasks}%{k}"),
            None => format!("1-{tasks}"),
        };
        let mut array = header(
            slurm,
            name,
            &self.logs.join(format!("{name}_%A_%a.out")),
            slurm.time.as_deref(),
            slurm.mem.as_deref(),
            self.chdir,
        )?;
        array.push_str(&format!("#SBATCH --array={array_range}\n"));
        array.push_str(&prologue(slurm));
        Ok(array)
    }

    /// The merge job up to its command (`--merge-time` and `--merge-mem`
    /// default to the tasks' settings).
    fn merge_start(&self) -> Result<String> {
        let (slurm, name) = (self.slurm, &self.slurm.job_name);
        let mut merge = header(
            slurm,
            &format!("{name}-merge"),
            &self.logs.join(format!("{name}-merge_%j.out")),
            slurm.merge_time.as_deref().or(slurm.time.as_deref()),
            slurm.merge_mem.as_deref().or(slurm.mem.as_deref()),
            self.chdir,
        )?;
        merge.push_str(&prologue(slurm));
        Ok(merge)
    }

    /// A compare sweep's commands: a shard per array task, the merge, and
    /// with `references_job` the references job's whole script.
    fn compare_commands(
        &self,
        args: &[String],
        references_job: bool,
        array: &mut String,
        merge: &mut String,
    ) -> Result<Option<String>> {
        let (penumbra, out, tasks) = (self.penumbra, self.out, self.tasks);
        // The reference cache must be shared by every task: the
        // default (~/.cache) is not always on a shared filesystem.
        let args = &if args
            .iter()
            .any(|a| a == "--cache-dir" || a.starts_with("--cache-dir="))
        {
            args.to_vec()
        } else {
            [
                args,
                &[
                    "--cache-dir".to_string(),
                    out.join("cache").display().to_string(),
                ],
            ]
            .concat()
        };
        // What belongs to the merge: --report (a shard refuses it)
        // and --no-images (the merge must be told the shards had none).
        let (args, merge_words) = &split_merge_args(args);
        let shards = out.join("shards");
        array.push_str(&format!(
            "{}{} --shard {TASK}/{tasks} --out {}\n",
            command(
                penumbra,
                &[&["compare".to_string()], args.as_slice()].concat()
            )?,
            threads(args),
            quote_path(&shards)?,
        ));
        merge.push_str(&format!(
            "{} --merge {} --out {}\n",
            command(
                penumbra,
                &[&["compare".to_string()], merge_words.as_slice()].concat()
            )?,
            quote_path(&shards)?,
            quote_path(out)?,
        ));
        if !references_job {
            return Ok(None);
        }
        let name = &self.slurm.job_name;
        let mut references = header(
            self.slurm,
            &format!("{name}-refs"),
            &self.logs.join(format!("{name}-refs_%j.out")),
            self.slurm.time.as_deref(),
            self.slurm.mem.as_deref(),
            self.chdir,
        )?;
        references.push_str(&prologue(self.slurm));
        references.push_str(&format!(
            "{}{} --references-only --out {}\n",
            command(
                penumbra,
                &[&["compare".to_string()], args.as_slice()].concat()
            )?,
            threads(args),
            quote_path(&out.join("references"))?,
        ));
        Ok(Some(references))
    }

    /// A banded render's commands: a band per array task, then
    /// `merge-tiles` of every part.
    fn render_commands(
        &self,
        scene: &Path,
        args: &[String],
        array: &mut String,
        merge: &mut String,
    ) -> Result<()> {
        let (penumbra, out, tasks) = (self.penumbra, self.out, self.tasks);
        let tiles = out.join("tiles");
        let words = [&["render".to_string(), scene.display().to_string()], args].concat();
        array.push_str(&format!(
            "{}{} --tiles {TASK}/{tasks} -o {}/{TASK}.part\n",
            command(penumbra, &words)?,
            threads(args),
            quote_path(&tiles)?,
        ));
        merge.push_str(&format!(
            "parts=()\nfor i in $(seq 1 {tasks}); do parts+=({}/\"$i\".part); done\n\
             {} \"${{parts[@]}}\" -o {} --exr {}\n",
            quote_path(&tiles)?,
            command(penumbra, &["merge-tiles".to_string()])?,
            quote_path(&out.join("render.png"))?,
            quote_path(&out.join("render.exr"))?,
        ));
        Ok(())
    }
}

/// Splits forwarded compare arguments into the shards' and the extra
/// words of the merge: `--report PATH` goes to the merge only,
/// `--no-images` to both.
fn split_merge_args(args: &[String]) -> (Vec<String>, Vec<String>) {
    let (mut shard, mut merge) = (Vec::new(), Vec::new());
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--report" {
            merge.push(a.clone());
            merge.extend(it.next().cloned());
        } else if a.starts_with("--report=") {
            merge.push(a.clone());
        } else {
            if a == "--no-images" {
                merge.push(a.clone());
            }
            shard.push(a.clone());
        }
    }
    (shard, merge)
}

/// The job id in `sbatch --parsable`'s output (`ID` or `ID;CLUSTER`).
pub fn parse_job_id(stdout: &str) -> Result<String> {
    let line = stdout
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("");
    let id = line.split(';').next().unwrap_or("");
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(Error::param(
            "--submit",
            format!("sbatch --parsable printed {stdout:?}, not a job id"),
        ));
    }
    Ok(id.to_string())
}

/// Runs `sbatch --parsable [extra] script` and returns the job id.
pub fn sbatch(sbatch: &Path, extra: &[String], script: &Path) -> Result<String> {
    let out = Command::new(sbatch)
        .arg("--parsable")
        .args(extra)
        .arg(script)
        .output()
        .map_err(|e| Error::io(sbatch, e))?;
    if !out.status.success() {
        return Err(Error::param(
            "--submit",
            format!(
                "{} {} failed ({}): {}",
                sbatch.display(),
                script.display(),
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        ));
    }
    parse_job_id(&String::from_utf8_lossy(&out.stdout))
}

/// Job ids of a submitted sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Submitted {
    /// The references job.
    pub references: Option<String>,
    /// The array job.
    pub array: String,
    /// The merge job.
    pub merge: String,
}

/// Submits `scripts` (already written): references, then the array
/// depending on it, then the merge depending on the array (`afterok`: a
/// failed task cancels the merge, given `kill_invalid_depend`, instead
/// of leaving it pending).
pub fn submit(sbatch_cmd: &Path, scripts: &Scripts) -> Result<Submitted> {
    submit_counted(sbatch_cmd, scripts, &mut Vec::new())
}

/// [`submit`], recording each job id in `done` as it is queued (so that
/// a failure knows what is already queued).
fn submit_counted(
    sbatch_cmd: &Path,
    scripts: &Scripts,
    done: &mut Vec<String>,
) -> Result<Submitted> {
    let mut queue = |extra: &[String], script: &Path| -> Result<String> {
        let id = sbatch(sbatch_cmd, extra, script)?;
        done.push(id.clone());
        Ok(id)
    };
    let references = match &scripts.references {
        Some((path, _)) => Some(queue(&[], path)?),
        None => None,
    };
    let after = |id: &str| vec![format!("--dependency=afterok:{id}")];
    let array = queue(
        &references.as_deref().map(after).unwrap_or_default(),
        &scripts.array.0,
    )?;
    let merge = queue(&after(&array), &scripts.merge.0)?;
    Ok(Submitted {
        references,
        array,
        merge,
    })
}

/// Checks that `program` can be run: a path must be a file, a bare name
/// must be found in `PATH`; the error names `--sbatch`.
fn find_program(program: &Path) -> Result<()> {
    let is_file = |p: &Path| p.metadata().is_ok_and(|m| m.is_file());
    let found = if program.components().count() > 1 || program.is_absolute() {
        is_file(program)
    } else {
        std::env::var_os("PATH")
            .is_some_and(|path| std::env::split_paths(&path).any(|d| is_file(&d.join(program))))
    };
    if found {
        Ok(())
    } else {
        Err(Error::param(
            "--sbatch",
            format!(
                "{} not found (is Slurm installed here?); nothing was written. Without \
                 --submit the scripts are written for submitting by hand",
                program.display()
            ),
        ))
    }
}

/// What one sweep created on disk (directories that did not exist, files
/// that did not), to remove again when the sweep fails before anything
/// was submitted.
#[derive(Debug, Default)]
struct Created {
    dirs: Vec<PathBuf>,
    files: Vec<PathBuf>,
}

impl Created {
    /// `create_dir_all(dir)`, recording each directory it makes.
    fn dirs(&mut self, dir: &Path) -> Result<()> {
        let missing: Vec<PathBuf> = dir
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
            .map(Path::to_path_buf)
            .collect();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        // Outermost first, so that removal in reverse goes inside out.
        self.dirs.extend(missing.into_iter().rev());
        Ok(())
    }

    /// Removes what was recorded: files, then directories inside out, and
    /// only empty ones (anything else in them is not ours).
    fn remove(&self) {
        for f in &self.files {
            let _ = std::fs::remove_file(f);
        }
        for d in self.dirs.iter().rev() {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// `penumbra sweep`.
pub fn run_sweep(args: SweepArgs) -> Result<()> {
    let (work, tasks) = match (&args.render, args.tiles, args.shards) {
        (Some(scene), Some(n), None) => (
            Work::Render {
                scene: scene.clone(),
                args: args.args.clone(),
            },
            n,
        ),
        (None, None, Some(n)) => (
            Work::Compare {
                args: args.args.clone(),
                references_job: args.references_job,
            },
            n,
        ),
        _ => {
            return Err(Error::param(
                "--shards",
                "give --shards N (a compare sweep) or --render SCENE --tiles N",
            ))
        }
    };
    if let Work::Compare { args: a, .. } = &work {
        if a.iter()
            .any(|w| w == "--out" || w == "--shard" || w.starts_with("--out="))
        {
            return Err(Error::param(
                "--",
                "the forwarded compare arguments must not set --out or --shard: the sweep does",
            ));
        }
    }
    let cwd = std::env::current_dir().map_err(|e| Error::io(".", e))?;
    let absolute = |p: &Path| {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            cwd.join(p)
        }
    };
    let out = absolute(&args.out);
    let penumbra = match &args.penumbra {
        Some(p) => absolute(p),
        None => std::env::current_exe().map_err(|e| Error::io("penumbra", e))?,
    };
    let scripts = scripts(&work, tasks, &out, &cwd, &penumbra, &args.job)?;
    let all: Vec<&(PathBuf, String)> = scripts
        .references
        .iter()
        .chain([&scripts.array, &scripts.merge])
        .collect();
    if args.dry_run {
        for (path, text) in &all {
            write_stdout(&format!("# ---- {}\n{text}", path.display()))?;
        }
        return Ok(());
    }
    let logs = args
        .job
        .log_dir
        .clone()
        .map(|p| absolute(&p))
        .unwrap_or_else(|| out.join("logs"));
    let sub = match work {
        Work::Compare { .. } => "shards",
        Work::Render { .. } => "tiles",
    };
    if args.submit {
        // Before anything is written: without Slurm there is nothing to
        // submit to, and no folders to leave behind.
        find_program(&args.sbatch)?;
    }
    let mut created = Created::default();
    let written = (|| -> Result<()> {
        for d in [out.join("slurm"), logs, out.join(sub)] {
            created.dirs(&d)?;
        }
        for (path, text) in &all {
            let existed = path.exists();
            write_atomically(path, |tmp| {
                std::fs::write(tmp, text).map_err(|e| Error::io(tmp, e))
            })?;
            if !existed {
                created.files.push(path.clone());
            }
        }
        Ok(())
    })();
    if let Err(e) = written {
        created.remove();
        return Err(e);
    }
    let rerun = format!(
        "re-run task I alone: sbatch --array=I {}; then sbatch {}\n",
        scripts.array.0.display(),
        scripts.merge.0.display()
    );
    if args.submit {
        let mut done = Vec::new();
        let ids = match submit_counted(&args.sbatch, &scripts, &mut done) {
            Ok(ids) => ids,
            // Nothing queued: nothing of this run is worth keeping.
            Err(e) if done.is_empty() => {
                created.remove();
                return Err(e);
            }
            // A queued job needs its scripts and log folder: keep them.
            Err(e) => {
                return Err(Error::param(
                    "--submit",
                    format!(
                        "{e}; job(s) {} were already submitted (scancel them, or \
                         submit the rest by hand)",
                        done.join(", ")
                    ),
                ))
            }
        };
        let mut s = String::new();
        if let Some(r) = &ids.references {
            s.push_str(&format!("references job {r}\n"));
        }
        s.push_str(&format!(
            "array job {} ({tasks} tasks)\nmerge job {} (afterok:{})\n{rerun}",
            ids.array, ids.merge, ids.array
        ));
        write_stdout(&s)?;
    } else {
        let mut s = String::from("wrote");
        for (path, _) in &all {
            s.push_str(&format!(" {}", path.display()));
        }
        s.push_str(&format!(
            "\nsubmit with --submit, or: a=$(sbatch --parsable {}) && sbatch --dependency=afterok:$a {}\n{rerun}",
            scripts.array.0.display(),
            scripts.merge.0.display()
        ));
        write_stdout(&s)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct T {
        #[command(flatten)]
        s: SlurmArgs,
    }

    fn slurm(args: &[&str]) -> SlurmArgs {
        T::parse_from(std::iter::once("t").chain(args.iter().copied())).s
    }

    #[test]
    fn array_script_carries_every_setting() {
        let s = slurm(&[
            "--partition=gpu",
            "--time=1:00:00",
            "--cpus-per-task=8",
            "--mem=16G",
            "--account=lab",
            "--qos=long",
            "--throttle=3",
            "--job-name=sw",
            "--sbatch-arg=--mail-type=END",
            "--setup=module load x",
        ]);
        let work = Work::Compare {
            args: vec!["a b.toml".into(), "--techniques".into(), "dcs".into()],
            references_job: true,
        };
        let sc = scripts(
            &work,
            4,
            Path::new("/o"),
            Path::new("/w"),
            Path::new("/bin/p"),
            &s,
        )
        .unwrap();
        let a = &sc.array.1;
        for want in [
            "#SBATCH --array=1-4%3\n",
            "#SBATCH --partition=gpu\n",
            "#SBATCH --time=1:00:00\n",
            "#SBATCH --cpus-per-task=8\n",
            "#SBATCH --mem=16G\n",
            "#SBATCH --account=lab\n",
            "#SBATCH --qos=long\n",
            "#SBATCH --job-name=sw\n",
            "#SBATCH --output='/o/logs/sw_%A_%a.out'\n",
            "#SBATCH --mail-type=END\n",
            "#SBATCH --chdir=/w\n",
            "module load x\n",
            "/bin/p compare 'a b.toml' --techniques dcs --cache-dir /o/cache --threads \"${SLURM_CPUS_PER_TASK:-1}\" \
             --shard \"$SLURM_ARRAY_TASK_ID\"/4 --out /o/shards\n",
        ] {
            assert!(a.contains(want), "{want:?} not in\n{a}");
        }
        assert!(
            sc.merge
                .1
                .contains("/bin/p compare --merge /o/shards --out /o\n"),
            "{}",
            sc.merge.1
        );
        assert!(!sc.merge.1.contains("--array"));
        assert!(sc.references.unwrap().1.contains("--references-only"));
        let work = Work::Compare {
            args: ["s.toml", "--report", "r.md", "--no-images"]
                .map(String::from)
                .to_vec(),
            references_job: false,
        };
        let sc = scripts(
            &work,
            2,
            Path::new("/o"),
            Path::new("/w"),
            Path::new("/p"),
            &s,
        )
        .unwrap();
        assert!(!sc.array.1.contains("r.md") && sc.array.1.contains("s.toml --no-images"));
        assert!(
            sc.merge
                .1
                .contains("/p compare --report r.md --no-images --merge /o/shards --out /o\n"),
            "{}",
            sc.merge.1
        );
        assert_eq!(sc.array.0, Path::new("/o/slurm/array.sbatch"));
    }

    #[test]
    fn render_sweep_and_refusals() {
        let s = slurm(&["--cpus-per-task=2"]);
        let work = Work::Render {
            scene: "s.toml".into(),
            args: vec!["--threads".into(), "1".into()],
        };
        let sc = scripts(
            &work,
            4,
            Path::new("/o"),
            Path::new("/w"),
            Path::new("/p"),
            &s,
        )
        .unwrap();
        assert!(sc.array.1.contains(
            "/p render s.toml --threads 1 --tiles \"$SLURM_ARRAY_TASK_ID\"/4 -o /o/tiles/\"$SLURM_ARRAY_TASK_ID\".part\n"
        ), "{}", sc.array.1);
        assert!(sc.array.1.contains("#SBATCH --array=1-4\n"));
        assert!(sc
            .merge
            .1
            .contains("merge-tiles \"${parts[@]}\" -o /o/render.png --exr /o/render.exr"));
        let bad = slurm(&["--sbatch-arg=mail"]);
        assert!(scripts(
            &work,
            4,
            Path::new("/o"),
            Path::new("/w"),
            Path::new("/p"),
            &bad
        )
        .is_err());
        assert!(scripts(
            &work,
            0,
            Path::new("/o"),
            Path::new("/w"),
            Path::new("/p"),
            &s
        )
        .is_err());
    }

    #[test]
    fn job_ids() {
        assert_eq!(parse_job_id("1234\n").unwrap(), "1234");
        assert_eq!(parse_job_id("77;cluster\n").unwrap(), "77");
        assert!(parse_job_id("Submitted batch job 5\n").is_err());
        assert!(parse_job_id("").is_err());
    }

    /// Every quoted word reads back as itself through a POSIX shell
    /// split, alone and as part of a command line; plain words stay bare.
    #[test]
    fn quoting_round_trips_through_a_shell_split() {
        let words = [
            "it's",
            "",
            "a b.toml",
            "/o/logs/sw_%A_%a.out",
            "$HOME",
            "say \"hi\"",
            "back\\slash",
            "tab\there",
            "glob*?[x]",
            "--opt=a,b;c&d|e",
            "~user",
            "{a,b}",
            "äöü",
            "!bang^",
        ];
        for word in words {
            let quoted = shell_quote(word).unwrap();
            assert_eq!(
                shlex::split(&quoted),
                Some(vec![word.to_string()]),
                "{word:?} quoted as {quoted}"
            );
        }
        let line = command(Path::new("/bin/pen umbra"), &words.map(String::from)).unwrap();
        let mut expected = vec!["/bin/pen umbra".to_string()];
        expected.extend(words.map(String::from));
        assert_eq!(shlex::split(&line), Some(expected), "{line}");
        for plain in ["dcs", "--samples", "/o/shards", "1:00:00", "16G"] {
            assert_eq!(shell_quote(plain).unwrap(), plain);
        }
        assert!(shell_quote("nul\0byte").is_err());
    }

    /// The scripts of every kind of sweep, with awkward paths and words,
    /// are valid bash, their shebang (`bash -n` parses them without
    /// running anything; the merge of a banded render uses an array).
    #[test]
    fn scripts_are_valid_sh() {
        let s = slurm(&["--job-name=it's", "--mem=4G", "--setup=module load x"]);
        let works = [
            Work::Compare {
                args: [
                    "a b.toml",
                    "--report",
                    "r's.md",
                    "--techniques=dcs,reference",
                ]
                .map(String::from)
                .to_vec(),
                references_job: true,
            },
            Work::Render {
                scene: "my scene.toml".into(),
                args: vec!["--samples".into(), "$16".into()],
            },
        ];
        let dir = std::env::temp_dir().join(format!("penumbra-sh-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for work in &works {
            let sc = scripts(
                work,
                3,
                Path::new("/o ut/%x"),
                Path::new("/w'd"),
                Path::new("/bin/p q"),
                &s,
            )
            .unwrap();
            for (_, text) in sc.references.iter().chain([&sc.array, &sc.merge]) {
                let file = dir.join("job.sbatch");
                std::fs::write(&file, text).unwrap();
                let status = std::process::Command::new("bash")
                    .arg("-n")
                    .arg(&file)
                    .status()
                    .unwrap();
                assert!(status.success(), "bash -n refused\n{text}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
