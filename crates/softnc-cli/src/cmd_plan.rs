//! `softnc plan FILE`: read, check and plan a program; print a summary or canonical motions.

use anyhow::{Context, Result};
use softnc_gcode::{MotionKind, Program};
use softnc_machine::MachineProfile;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `softnc plan`.
#[derive(clap::Args, Debug)]
pub struct PlanArgs {
    /// The G-code program.
    file: PathBuf,
    /// Machine profile (RON); default `config/machines/default.ron`.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Print one JSON summary object.
    #[arg(long, conflicts_with = "canon")]
    json: bool,
    /// Print the canonical motions as JSON lines (LinuxCNC's frame, mm). Soft limits
    /// are reported as warnings here: this is the program's reading, not a run.
    #[arg(long)]
    canon: bool,
    /// Plan even where the program leaves the machine's travel (offline analysis).
    #[arg(long)]
    ignore_soft_limits: bool,
    /// Start with the parameters of this LinuxCNC-style parameter file (`NUMBER
    /// VALUE` lines: work offsets 5221-5390, G28/G30 positions 5161-5189, G92
    /// 5210-5219, ...); a missing file means all 0.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// With --params: write the parameters as the program left them back to the
    /// file (atomically), as LinuxCNC does at the end of a run.
    #[arg(long, requires = "params")]
    save_params: bool,
    /// A folder searched for `NAME.ngc` when the program calls a subroutine it
    /// does not define (repeatable; the program's own folder is searched last).
    #[arg(long, value_name = "DIR")]
    subroutine_path: Vec<PathBuf>,
    /// The folder of the user M codes (M100–M199): `M1nn` there must be an
    /// executable file, else the program is refused where it uses it.
    #[arg(long, value_name = "DIR")]
    user_m_codes: Option<PathBuf>,
    /// The folder the program's `(LOGOPEN,name)`/`(LOGAPPEND,name)` log files are
    /// written into once it is read and planned (a name is a plain file name
    /// there); without it such a program is refused as unsupported.
    #[arg(long, value_name = "DIR")]
    log_dir: Option<PathBuf>,
}

impl PlanArgs {
    /// Whether reading needs more than the plain reader (parameters, search path).
    fn needs_options(&self) -> bool {
        self.params.is_some()
            || !self.subroutine_path.is_empty()
            || self.user_m_codes.is_some()
            || self.log_dir.is_some()
    }
}

/// Load a machine profile, or explain which field is wrong.
pub fn load_machine(path: Option<&PathBuf>) -> Result<MachineProfile> {
    let path = path.cloned().unwrap_or_else(crate::default_machine_path);
    Ok(MachineProfile::load(&path)?)
}

/// Read a program file and interpret it with `options` (the operator's switches).
/// `Err(Ok(msg))` is a refusal (exit 2).
pub fn read_file(
    file: &Path,
    machine: &MachineProfile,
    options: &softnc_gcode::ReadOptions,
) -> Result<Result<Program, String>> {
    let bytes = crate::program_file::read(file)
        .with_context(|| format!("cannot read {}", file.display()))?;
    let text = String::from_utf8_lossy(&bytes);
    let name = file.display().to_string();
    Ok(
        softnc_gcode::read_program_with(&text, &name, machine, options)
            .map(|(program, _)| program)
            .map_err(|e| e.to_string()),
    )
}

/// [`read_file`] with the parameter file and search path of `args`; writes the
/// parameters back when asked. `Err(Ok(msg))` is a refusal (exit 2).
fn read_file_with(args: &PlanArgs, machine: &MachineProfile) -> Result<Result<Program, String>> {
    let params = match &args.params {
        Some(path) => match softnc_gcode::Params::load(path) {
            Ok(p) => Some(p),
            Err(e) => return Ok(Err(format!("softnc: {e}"))),
        },
        None => None,
    };
    let options = softnc_gcode::ReadOptions {
        subroutine_path: args.subroutine_path.clone(),
        params,
        user_m_codes: args.user_m_codes.clone(),
        log_files: args.log_dir.is_some(),
        // the canonical reading is rs274's: M66's #5399 as its stand-alone
        // interpreter leaves it
        m66_results: if args.canon {
            softnc_gcode::M66Results::StandIn
        } else {
            softnc_gcode::M66Results::Refuse
        },
        // and a probe move's results are its stand-alone interpreter's
        probe_results: if args.canon {
            softnc_gcode::ProbeResults::StandIn
        } else {
            softnc_gcode::ProbeResults::Refuse
        },
        ..Default::default()
    };
    let bytes = crate::program_file::read(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let text = String::from_utf8_lossy(&bytes);
    let name = args.file.display().to_string();
    let (program, params) = match softnc_gcode::read_program_with(&text, &name, machine, &options) {
        Ok(r) => r,
        Err(e) => return Ok(Err(e.to_string())),
    };
    if let (true, Some(path)) = (args.save_params, &args.params) {
        if let Err(e) = params.save(path) {
            return Ok(Err(format!("softnc: {e}")));
        }
    }
    Ok(Ok(program))
}

pub fn run(args: PlanArgs) -> Result<ExitCode> {
    let machine = match load_machine(args.machine.as_ref()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let options = softnc_planner::PlanOptions {
        ignore_soft_limits: args.canon || args.ignore_soft_limits,
        user_m_codes: args.user_m_codes.clone(),
        ..Default::default()
    };
    if !args.canon && !args.needs_options() {
        return summary(&args, &machine, &options);
    }
    let program = match read_file_with(&args, &machine)? {
        Ok(p) => p,
        Err(msg) => {
            eprintln!("{msg}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    // the canonical motions are the program's reading; planning checks it plans
    // (not a reading with stand-in probe results: no machine stands where they say)
    let probes = program
        .motions
        .iter()
        .any(|m| matches!(m.kind, MotionKind::Probe { .. }));
    let plan = if args.canon && probes {
        eprintln!(
            "warning: {}: not planned: its probe moves (G38.x) were read with rs274's stand-in results",
            args.file.display()
        );
        None
    } else {
        match softnc_planner::plan(&program, &machine, &options) {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!("{e}");
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
        }
    };
    // the program is accepted: its log files are written
    if let Some(dir) = &args.log_dir {
        if let Err(e) = softnc_gcode::log_files::write(dir, &program.log_files) {
            eprintln!(
                "softnc: cannot write {}'s log files in {}: {e}",
                args.file.display(),
                dir.display()
            );
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    }
    if let (false, Some(plan)) = (args.canon, &plan) {
        return print_summary(&args, &program, &plan.stats());
    }
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for w in &program.warnings {
        eprintln!("warning: {w}");
    }
    write_canon(&mut out, &program)?;
    out.flush()?;
    Ok(ExitCode::SUCCESS)
}

/// The plan's summary: read and planned in one pass on two threads, keeping neither
/// the motions nor the path (`check_program_parallel`: the figures of the whole plan,
/// bit for bit, without its memory).
fn summary(
    args: &PlanArgs,
    machine: &MachineProfile,
    options: &softnc_planner::PlanOptions,
) -> Result<ExitCode> {
    let bytes = crate::program_file::read(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let name = args.file.display().to_string();
    // the bytes checked as UTF-8 as the reading thread reads them, not all before
    // the threads start (docs/perf-log/planner-figures.md, fifteenth round); a program that is
    // not UTF-8 is read again made UTF-8 (lossy), as before
    let read = match softnc_planner::check_program_parallel_bytes(&bytes, &name, machine, options) {
        Err(softnc_planner::ReadPlanError::Gcode(e))
            if e.kind == softnc_gcode::ErrorKind::NotUtf8 =>
        {
            let text = String::from_utf8_lossy(&bytes);
            softnc_planner::check_program_parallel(&text, &name, machine, options)
        }
        read => read,
    };
    let (program, checked) = match read {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    print_summary(args, &program, &checked.stats())
}

/// Print the summary of a read and planned program.
fn print_summary(
    args: &PlanArgs,
    program: &Program,
    s: &softnc_planner::PlanStats,
) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for w in &program.warnings {
        eprintln!("warning: {w}");
    }
    let summary = serde_json::json!({
        "file": program.file,
        "blocks": program.blocks,
        "moves": s.moves,
        "path_length_mm": s.path_length_mm,
        "duration_s": s.duration_s,
        "samples": s.samples,
        "max_feed_mm_min": s.max_feed_mm_min,
        "bounds_mm": {"min": s.bounds_min_mm.0, "max": s.bounds_max_mm.0},
        "warnings": program.warnings,
    });
    if args.json {
        writeln!(out, "{summary}")?;
    } else {
        writeln!(
            out,
            "{}: {} blocks, {} moves, {:.3} mm, planned {:.3} s ({} samples), max feed {:.1} mm/min",
            program.file,
            program.blocks,
            s.moves,
            s.path_length_mm,
            s.duration_s,
            s.samples,
            s.max_feed_mm_min
        )?;
    }
    out.flush()?;
    Ok(ExitCode::SUCCESS)
}

/// A machine operation as a JSON line: its canonical call and its arguments.
fn machine_json(line: u32, op: &softnc_gcode::MachineOp, program: &Program) -> serde_json::Value {
    use softnc_gcode::MachineOp as Op;
    let mut v = serde_json::json!({"line": line, "kind": "machine", "canon": op.canon_name()});
    let args = match *op {
        Op::SpindleOn { rpm, .. } => serde_json::json!({"rpm": rpm}),
        Op::SpindleOrient {
            angle_deg,
            direction,
            timeout_s,
        } => {
            serde_json::json!({"angle_deg": angle_deg, "direction": direction, "timeout_s": timeout_s})
        }
        Op::Coolant { which, on } => serde_json::json!({
            "coolant": match which {
                softnc_gcode::CoolantLine::Mist => "mist",
                softnc_gcode::CoolantLine::Flood => "flood",
            },
            "on": on}),
        Op::ToolPrepare { tool } | Op::ToolChange { tool } => serde_json::json!({"tool": tool}),
        Op::Message { index, .. } => serde_json::json!({
            "text": program.messages.get(index as usize)}),
        Op::DigitalOut { line, .. } => serde_json::json!({"output": line}),
        Op::AnalogOut { line, value, .. } => serde_json::json!({"output": line, "value": value}),
        Op::WaitInput {
            input,
            mode,
            timeout_s,
        } => serde_json::json!({
            "input": format!("{input:?}"), "mode": format!("{mode:?}"), "timeout_s": timeout_s}),
        Op::UserM { code, p, q } => serde_json::json!({"code": code, "p": p, "q": q}),
        Op::SpindleOff | Op::Overrides { .. } => serde_json::json!({}),
    };
    if let (Some(o), serde_json::Value::Object(a)) = (v.as_object_mut(), args) {
        o.extend(a);
    }
    v
}

fn write_canon(out: &mut impl Write, program: &Program) -> Result<()> {
    for m in &program.motions {
        // positions as LinuxCNC's canonical output prints them (4 decimals, program units)
        let (end, center) = m.canon_view();
        let end = end.map(|e| e.0);
        let obj = match m.kind {
            MotionKind::Traverse { .. } => serde_json::json!({
                "line": m.line, "kind": "traverse", "end": end, "feed_mm_min": null}),
            MotionKind::Feed {
                feed_mm_per_min, ..
            } => serde_json::json!({
                "line": m.line, "kind": "feed", "end": end, "feed_mm_min": feed_mm_per_min}),
            MotionKind::Arc {
                plane,
                turns,
                feed_mm_per_min,
                ..
            } => serde_json::json!({
                "line": m.line, "kind": "arc", "end": end, "feed_mm_min": feed_mm_per_min,
                "plane": plane.name(), "center": center.map(|c| c.0), "turns": turns}),
            MotionKind::Dwell { seconds } => serde_json::json!({
                "line": m.line, "kind": "dwell", "seconds": seconds}),
            // rs274 prints PROGRAM_STOP() / OPTIONAL_PROGRAM_STOP()
            MotionKind::Pause { optional } => serde_json::json!({
                "line": m.line, "kind": if optional { "optional_stop" } else { "program_stop" }}),
            MotionKind::Sync => serde_json::json!({"line": m.line, "kind": "sync"}),
            // rs274 prints STRAIGHT_PROBE(x, y, z, …)
            MotionKind::Probe {
                feed_mm_per_min,
                probe,
                ..
            } => serde_json::json!({
                "line": m.line, "kind": "probe", "end": end, "feed_mm_min": feed_mm_per_min,
                "g": probe.name()}),
            // the machine around the axes, by LinuxCNC's canonical call
            MotionKind::Machine(op) => machine_json(m.line, &op, program),
        };
        writeln!(out, "{obj}")?;
    }
    Ok(())
}
