//! `softnc learn FILE --machine P --iterations K [--law markov|radius] [--json]`: run a
//! job repeatedly on the simulated machine, learning its errors away (paper 002 eq 5
//! or paper 004 eq 8–9), and keep the result in the learning store;
//! `softnc learn list|show|clear` manage the store.
//!
//! The store folder: `--store DIR`, else `$SOFTNC_LEARNING_DIR`, else
//! `$XDG_DATA_HOME/softnc/learning`, else `$HOME/.local/share/softnc/learning`, else
//! `./.softnc/learning`. An entry is keyed by the SHA-256 of the job file, of the
//! machine profile file and the feed override (100 %): a changed job or profile has
//! another key, so its old entry is never applied (`list` marks it stale).

use crate::cmd_plan::load_machine;
use anyhow::{Context, Result};
use softnc_experiments::learning_runs::{self as learn_sim, IterationStats, PreparedJob};
use softnc_learning::entry::{store_dir, Law, LawState, Learned, OVERRIDE_PCT};
use softnc_learning::markov::{Improvement, MarkovJob};
use softnc_learning::radius_ilc::RadiusIlc;
use softnc_learning::{LearningKey, LearningStore};
use softnc_sim::{simulated_engine, SimOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub use softnc_learning::markov::DEFAULT_GAIN;

/// The learning law, as `--law` names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LawArg {
    /// Paper 002 eq 5: Markov-parameter learning of the command samples.
    Markov,
    /// Paper 004 eq 8–9: per-degree radius learning of one circle.
    Radius,
}

impl From<LawArg> for Law {
    fn from(l: LawArg) -> Law {
        match l {
            LawArg::Markov => Law::Markov,
            LawArg::Radius => Law::Radius,
        }
    }
}

/// Arguments of `softnc learn`.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct LearnArgs {
    #[command(subcommand)]
    action: Option<StoreCmd>,
    /// The G-code program to learn (for `--law radius`: one full circle).
    file: Option<PathBuf>,
    /// Machine profile (default `config/machines/default.ron`).
    #[arg(long, global = true)]
    machine: Option<PathBuf>,
    /// Learning repetitions after the first run.
    #[arg(long, default_value_t = 10)]
    iterations: usize,
    /// The learning law.
    #[arg(long, value_enum, default_value_t = LawArg::Markov)]
    law: LawArg,
    /// Print `{"iterations":[{"iteration","rms_um","max_abs_um"}, …]}` (the first
    /// entry is the run before any learning).
    #[arg(long, global = true)]
    json: bool,
    /// Markov law: learning gain s (see docs/controllers.md for the choice).
    #[arg(long, default_value_t = DEFAULT_GAIN)]
    gain: f64,
    /// Markov law: instead of --gain, per axis the LTI bound 1/(Σ_all|h|·Σ_p|h|) of
    /// the identified parameters (monotone for an LTI loop).
    #[arg(long)]
    lti_gain: bool,
    /// Markov law: learning buffer size p (Markov terms; default: all, the job's length).
    #[arg(long)]
    buffer: Option<usize>,
    /// Radius law: learning rate α of eq 8.
    #[arg(long, default_value_t = 1.0)]
    alpha: f64,
    /// Random seed of the simulated machine (default: the profile's `servo.seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Learning store folder (see the module docs for the default).
    #[arg(long, global = true)]
    store: Option<PathBuf>,
    /// Continue from the stored entry of this job (its correction and error buffer)
    /// instead of starting afresh.
    #[arg(long)]
    resume: bool,
}

#[derive(clap::Subcommand)]
enum StoreCmd {
    /// List the stored entries (stale = their job or profile file changed or is gone).
    List,
    /// Show the entry of FILE on --machine.
    Show {
        /// The G-code program.
        file: PathBuf,
    },
    /// Remove the entry of FILE on --machine, or `--all` entries, or the `--stale` ones.
    Clear {
        /// The G-code program.
        file: Option<PathBuf>,
        /// Remove every entry (and files left by killed writers).
        #[arg(long)]
        all: bool,
        /// Remove the entries whose job or profile changed or is gone.
        #[arg(long)]
        stale: bool,
    },
}

fn machine_path(p: Option<&PathBuf>) -> PathBuf {
    p.cloned().unwrap_or_else(crate::default_machine_path)
}

fn key_of(job: &Path, machine: &Path) -> Result<LearningKey> {
    let j = std::fs::read(job).with_context(|| format!("cannot read {}", job.display()))?;
    let m = std::fs::read(machine).with_context(|| format!("cannot read {}", machine.display()))?;
    Ok(LearningKey::new(&j, &m, OVERRIDE_PCT))
}

/// Run `softnc learn`.
#[allow(clippy::too_many_lines)]
pub fn run(args: LearnArgs) -> Result<ExitCode> {
    let law = Law::from(args.law);
    let store = LearningStore::new(store_dir(args.store.as_deref()));
    match &args.action {
        Some(StoreCmd::List) => return list(&store, args.json),
        Some(StoreCmd::Show { file }) => {
            let key = key_of(file, &machine_path(args.machine.as_ref()))?;
            return show(&store, &key, file, args.json);
        }
        Some(StoreCmd::Clear { file, all, stale }) => {
            return clear(&store, file.as_ref(), args.machine.as_ref(), *all, *stale)
        }
        None => {}
    }
    let Some(file) = args.file.clone() else {
        eprintln!("softnc learn: give a G-code FILE, or one of list, show, clear");
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    };
    let mpath = machine_path(args.machine.as_ref());
    let machine = match load_machine(Some(&mpath)) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let key = key_of(&file, &mpath)?;
    let text = String::from_utf8_lossy(&std::fs::read(&file)?).into_owned();
    let name = file.display().to_string();
    let seed = args.seed.unwrap_or(machine.servo.seed);
    let previous: Option<Learned> = if args.resume {
        store.get::<Learned>(&key)?.filter(|e| e.law() == law)
    } else {
        None
    };
    if !(args.gain.is_finite() && args.gain > 0.0) {
        eprintln!(
            "softnc learn: --gain must be a positive number, not {}",
            args.gain
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    if law == Law::Radius && !(args.alpha.is_finite() && args.alpha > 0.0) {
        eprintln!(
            "softnc learn: --alpha must be a positive number, not {}",
            args.alpha
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    if args.buffer == Some(0) {
        eprintln!("softnc learn: --buffer must be at least 1");
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    let mut entry = Learned {
        job_file: name.clone(),
        profile_file: mpath.display().to_string(),
        seed,
        iterations: previous
            .as_ref()
            .map(|p| p.iterations.clone())
            .unwrap_or_default(),
        state: LawState::Markov(MarkovJob::new(Default::default(), 1, Some(1.0), 0)),
    };
    let first = entry.iterations.len();
    let mut engine = simulated_engine(&machine, seed, SimOptions::default());
    // the entry is written after every run: a killed run keeps what it had learnt
    let put = |entry: &Learned| {
        store
            .put(&key, entry)
            .map_err(|e| format!("learning store: {e}"))
    };
    // Markov law: the kept correction's improvement (None: nothing improved)
    let mut kept = None;
    let mut stopped = false;
    let result = match law {
        Law::Markov => {
            let job = match PreparedJob::new(&text, &name, &machine) {
                Ok(j) => j,
                Err(msg) => {
                    eprintln!("{msg}");
                    return Ok(ExitCode::from(crate::EXIT_REFUSED));
                }
            };
            let mut mj = match previous.map(|p| p.state) {
                Some(LawState::Markov(mj)) if mj.samples() == job.samples.len() => mj,
                _ => {
                    let n = job.samples.len();
                    let h = learn_sim::identify(&mut engine, &machine, job.samples[0].pos_mm.0, n)
                        .map_err(anyhow::Error::msg)?;
                    let bound = learn_sim::correction_bound_mm(&machine, &h);
                    MarkovJob::new(
                        h,
                        args.buffer.unwrap_or(n),
                        (!args.lti_gain).then_some(args.gain),
                        n,
                    )
                    .bounded(bound)
                }
            };
            // only a correction measured to improve on the unlearned run is stored
            // (written as soon as it is the best: a killed run keeps it)
            let r =
                learn_sim::learn_markov(&mut engine, &job, &mut mj, args.iterations, |st, mj| {
                    let mut st = *st;
                    st.iteration += first;
                    entry.iterations.push(st);
                    if mj.improvement.is_some() {
                        entry.state = LawState::Markov(mj.clone());
                        put(&entry)?;
                    }
                    Ok(())
                });
            if r.is_ok() {
                let mj = renumbered(&mj, first);
                if mj.improvement.is_some() {
                    entry.state = LawState::Markov(mj.clone());
                    put(&entry).map_err(anyhow::Error::msg)?;
                }
                kept = Some(mj.improvement);
                if let Ok(its) = &r {
                    stopped = its.len() < args.iterations + 1;
                }
            }
            r
        }
        Law::Radius => {
            let (circle, radius_mm) = match learn_sim::find_circle(&text, &name, &machine) {
                Ok(c) => c,
                Err(msg) => {
                    eprintln!("{msg}");
                    return Ok(ExitCode::from(crate::EXIT_REFUSED));
                }
            };
            let mut ilc = match previous.map(|p| p.state) {
                Some(LawState::Radius { ilc, .. }) => ilc,
                _ => RadiusIlc::new(radius_mm, args.alpha),
            };
            // as for the Markov law: only command radii whose run improved on the
            // unlearned run (the entry's first) are stored, the best so far
            let mut best: Option<Improvement> = None;
            let r = learn_sim::learn_radius(
                &mut engine,
                &machine,
                &circle,
                &mut ilc,
                args.iterations,
                |st, ilc, err| {
                    let mut st = *st;
                    st.iteration += first;
                    entry.iterations.push(st);
                    let candidate = Improvement {
                        iteration: st.iteration,
                        unlearned_rms_um: entry.iterations[0].rms_um,
                        rms_um: st.rms_um,
                    };
                    if candidate.improved() && best.is_none_or(|b| candidate.rms_um < b.rms_um) {
                        best = Some(candidate);
                        entry.state = LawState::Radius {
                            circle,
                            ilc: ilc.clone(),
                            last_error_mm: err.to_vec(),
                        };
                        put(&entry)?;
                    }
                    Ok(())
                },
            );
            if let Ok(its) = &r {
                if best.is_some() {
                    put(&entry).map_err(anyhow::Error::msg)?;
                }
                kept = Some(best);
                stopped = its.len() < args.iterations + 1;
            }
            r
        }
    };
    if let Err(msg) = result {
        eprintln!("softnc learn: {msg}");
        return Ok(ExitCode::from(1));
    }
    print_iterations(&entry, law, args.json)?;
    if !args.json {
        if stopped {
            match law {
                Law::Markov => eprintln!(
                    "stopped: {} learning steps in a row did not reduce the error (the gain was halved after each)",
                    learn_sim::FAILED_STEPS_TO_STOP
                ),
                Law::Radius => eprintln!(
                    "stopped: the last run was worse than the unlearned one (eq 8 diverging: a smaller --alpha)"
                ),
            }
        }
        match kept {
            Some(None) => {
                eprintln!(
                    "no run improved on the unlearned run: nothing stored (an earlier entry, if any, is left as it was)"
                );
                return Ok(ExitCode::from(1));
            }
            Some(Some(imp)) => eprintln!(
                "kept iteration {}: {:.3} µm RMS against {:.3} µm unlearned",
                imp.iteration, imp.rms_um, imp.unlearned_rms_um
            ),
            None => {}
        }
        eprintln!("stored in {}", store.dir().join(key.file_name()).display());
    } else if kept == Some(None) {
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// `mj` with its improvement numbered as the entry's runs (`first` runs before this
/// session's).
fn renumbered(mj: &MarkovJob, first: usize) -> MarkovJob {
    let mut mj = mj.clone();
    if let Some(i) = &mut mj.improvement {
        i.iteration += first;
    }
    mj
}

/// `{"iterations":[{"iteration":k,"rms_um":x,"max_abs_um":y}, …]}`.
pub fn iterations_json(its: &[IterationStats]) -> serde_json::Value {
    serde_json::json!({
        "iterations": its.iter().map(|s| serde_json::json!({
            "iteration": s.iteration,
            "rms_um": s.rms_um,
            "max_abs_um": s.max_abs_um,
        })).collect::<Vec<_>>()
    })
}

fn print_iterations(entry: &Learned, law: Law, json: bool) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if json {
        writeln!(out, "{}", iterations_json(&entry.iterations))?;
        return Ok(());
    }
    let what = match law {
        Law::Markov => "contour error",
        Law::Radius => "radius error per degree",
    };
    writeln!(out, "{} ({what}, µm)", entry.job_file)?;
    writeln!(out, "iteration      rms    max|e|      max      min   ‖e‖₂")?;
    let kept = entry.kept().map(|k| k.iteration);
    for s in &entry.iterations {
        writeln!(
            out,
            "{:>9} {:>8.3} {:>9.3} {:>8.3} {:>8.3} {:>9.2}{}",
            s.iteration,
            s.rms_um,
            s.max_abs_um,
            s.max_um,
            s.min_um,
            s.norm_um,
            if kept == Some(s.iteration) {
                "  ← kept"
            } else {
                ""
            }
        )?;
    }
    Ok(())
}

/// Whether an entry still belongs to its job and profile files.
fn status(key: &LearningKey, e: &Learned) -> &'static str {
    match key_of(Path::new(&e.job_file), Path::new(&e.profile_file)) {
        Err(_) => "stale (file gone)",
        Ok(k) if k.job_sha256 != key.job_sha256 => "stale (job changed)",
        Ok(k) if k.profile_sha256 != key.profile_sha256 => "stale (profile changed)",
        Ok(_) => "current",
    }
}

fn list(store: &LearningStore, json: bool) -> Result<ExitCode> {
    let entries = store.entries::<Learned>()?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if json {
        let v: Vec<_> = entries
            .iter()
            .map(|(k, e)| {
                serde_json::json!({
                    "entry": k.file_name(), "job": e.job_file, "profile": e.profile_file,
                    "law": e.law(), "runs": e.iterations.len(),
                    "last_rms_um": e.iterations.last().map(|s| s.rms_um),
                    "kept": e.kept().map(|k| serde_json::json!({
                        "iteration": k.iteration, "rms_um": k.rms_um,
                        "unlearned_rms_um": k.unlearned_rms_um,
                    })),
                    "status": status(k, e),
                })
            })
            .collect();
        writeln!(out, "{}", serde_json::Value::from(v))?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(out, "{}", store.dir().display())?;
    for (k, e) in &entries {
        let kept = match e.kept() {
            Some(i) => format!(
                "kept run {}: rms {:.3} µm (unlearned {:.3})",
                i.iteration, i.rms_um, i.unlearned_rms_um
            ),
            None => "no improvement recorded: not applied".into(),
        };
        writeln!(
            out,
            "{}  {:?}  {} runs, {kept}  {}  on {}  [{}]",
            k.file_name(),
            e.law(),
            e.iterations.len(),
            e.job_file,
            e.profile_file,
            status(k, e)
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

fn show(store: &LearningStore, key: &LearningKey, file: &Path, json: bool) -> Result<ExitCode> {
    let Some(e) = store.get::<Learned>(key)? else {
        eprintln!(
            "softnc learn: no entry for {} on this profile in {}",
            file.display(),
            store.dir().display()
        );
        return Ok(ExitCode::from(1));
    };
    if json {
        let mut v = iterations_json(&e.iterations);
        v["law"] = serde_json::to_value(e.law())?;
        v["entry"] = key.file_name().into();
        writeln!(std::io::stdout(), "{v}")?;
        return Ok(ExitCode::SUCCESS);
    }
    println!("{}  ({})", key.file_name(), status(key, &e));
    match &e.state {
        LawState::Markov(mj) => println!(
            "Markov law (002 eq 5): buffer p = {}, gain s = {:?}, {} samples, {} repetitions learnt",
            mj.buffer,
            mj.gain,
            mj.samples(),
            mj.repetitions
        ),
        LawState::Radius { ilc, .. } => {
            let (lo, hi) = ilc
                .radius_mm
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| (l.min(*r), h.max(*r)));
            println!(
                "radius law (004 eq 8–9): r_d = {} mm, α = {}, command radius {lo:.4}..{hi:.4} mm",
                ilc.desired_mm, ilc.alpha
            )
        }
    }
    print_iterations(&e, e.law(), false)?;
    Ok(ExitCode::SUCCESS)
}

fn clear(
    store: &LearningStore,
    file: Option<&PathBuf>,
    machine: Option<&PathBuf>,
    all: bool,
    stale: bool,
) -> Result<ExitCode> {
    let n = match (file, all, stale) {
        (Some(f), false, false) => store.clear(Some(&key_of(f, &machine_path(machine))?))?,
        (None, true, false) => {
            let n = store.clear(None)?;
            store.remove_leftovers()?;
            n
        }
        (None, false, true) => {
            let mut n = 0;
            for (k, e) in store.entries::<Learned>()? {
                if status(&k, &e) != "current" {
                    n += store.clear(Some(&k))?;
                }
            }
            n
        }
        _ => {
            eprintln!("softnc learn clear: give FILE, or --all, or --stale");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    println!("removed {n} entries from {}", store.dir().display());
    Ok(ExitCode::SUCCESS)
}
