//! Differential fuzzing of the language (parameters, expressions, O-word control
//! flow, subroutines) against LinuxCNC's own interpreter.
//!
//! Proptest draws random programs within the language (assignments to numbered,
//! local and global parameters; expressions with every operator and most
//! functions; `if/elseif/else`, `while`, `do/while`, `repeat`, `break`,
//! `continue`; subroutines with arguments and return values; `G0`/`G1` moves with
//! expression coordinates; `(DEBUG,…)` of values). Every program is read twice by
//! softnc: both readings must agree exactly and nothing may panic (this holds
//! without LinuxCNC, as on CI). Where `rs274` (LinuxCNC 2.9's stand-alone
//! interpreter) is installed, each program is also run with
//! `rs274 -v EMPTY.var -g FILE OUT` and the two readings must agree: both accept
//! or both reject (softnc on the line `rs274` names), the same moves (to the four
//! decimals `rs274` prints) and the same `(DEBUG,…)` messages. Without `rs274` a
//! note is printed and only the softnc checks run.
//!
//! `SOFTNC_DIFF_FUZZ_CASES=N` changes the number of programs (default 48).

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use softnc_core::MotionProfile;
use softnc_gcode::{GcodeError, MotionKind, ReadOptions};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

/// A small deterministic generator (xorshift64*), driven by proptest's seed.
struct Gen(u64);

impl Gen {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
    fn chance(&mut self, percent: u64) -> bool {
        self.below(100) < percent
    }
    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[self.below(items.len() as u64) as usize]
    }
    /// A number as a program writes it: integers and short decimals.
    fn number(&mut self) -> String {
        let v = self.below(2001) as f64 / 100.0 - 10.0;
        match self.below(3) {
            0 => format!("{}", v.round()),
            1 => format!("{v:.1}"),
            _ => format!("{v:.2}"),
        }
    }
}

/// What a generated program can read: parameters that have been given a value.
struct Scope {
    numbered: Vec<u32>,
    globals: Vec<String>,
    locals: Vec<String>,
}

const OPS: &[&str] = &[
    "+", "-", "*", "/", "**", "MOD", "EQ", "NE", "GT", "GE", "LT", "LE", "AND", "OR", "XOR",
];
/// The operators whose meaning is the same in every LinuxCNC 2.9 (see
/// [`Semantics`]).
const OPS_STABLE: &[&str] = &[
    "+", "-", "*", "/", "**", "MOD", "GT", "LT", "AND", "OR", "XOR",
];

/// Which LinuxCNC the installed `rs274` is. LinuxCNC 2.9.0 (commit 014777a816)
/// set `TOLERANCE_EQUAL` to 1e-6 and gave `LE`/`GE` that tolerance; earlier
/// snapshots (Debian 12's `2.9.0~pre1`) compare `EQ`/`NE` within 1e-4, `LE`/`GE`
/// exactly, and print `(DEBUG,…)` values under 1e-4 as 0. softnc reads as 2.9.0.
#[derive(Clone, Copy, PartialEq)]
enum Semantics {
    Release,
    PreRelease,
}

thread_local! {
    static SEMANTICS: std::cell::Cell<Semantics> = const { std::cell::Cell::new(Semantics::Release) };
}
const FUNCS: &[&str] = &[
    "ABS", "COS", "SIN", "TAN", "FIX", "FUP", "ROUND", "EXP", "LN", "SQRT", "ASIN", "ACOS",
];

fn value(g: &mut Gen, s: &Scope, depth: u32) -> String {
    let atom = depth == 0 || g.chance(40);
    if atom {
        let k = g.below(4);
        if k == 0 && !s.numbered.is_empty() {
            return format!("#{}", s.numbered[g.below(s.numbered.len() as u64) as usize]);
        }
        if k == 1 && !s.globals.is_empty() {
            return format!("#<{}>", s.globals[g.below(s.globals.len() as u64) as usize]);
        }
        if k == 2 && !s.locals.is_empty() {
            return format!("#<{}>", s.locals[g.below(s.locals.len() as u64) as usize]);
        }
        return g.number();
    }
    match g.below(5) {
        0 => format!("{}[{}]", g.pick(FUNCS), value(g, s, depth - 1)),
        1 => format!(
            "ATAN[{}]/[{}]",
            value(g, s, depth - 1),
            value(g, s, depth - 1)
        ),
        2 => format!("-{}", value(g, s, depth - 1)),
        _ => {
            let ops = if SEMANTICS.get() == Semantics::Release {
                OPS
            } else {
                OPS_STABLE
            };
            let mut e = format!("[{}", value(g, s, depth - 1));
            for _ in 0..=g.below(2) {
                e += &format!(" {} {}", g.pick(ops), value(g, s, depth - 1));
            }
            e + "]"
        }
    }
}

/// A bracketed expression.
fn expr(g: &mut Gen, s: &Scope) -> String {
    let v = value(g, s, 2);
    if v.starts_with('[') {
        v
    } else {
        format!("[{v}]")
    }
}

/// A program being generated.
struct Text {
    lines: Vec<String>,
    label: u32,
}

impl Text {
    fn push(&mut self, l: String) {
        self.lines.push(l);
    }
    fn label(&mut self) -> u32 {
        self.label += 1;
        self.label * 10
    }
}

fn statement(g: &mut Gen, p: &mut Text, s: &mut Scope, depth: u32, in_loop: Option<u32>) {
    match g.below(if depth == 0 { 5 } else { 11 }) {
        0 => {
            let n = 1 + g.below(9) as u32;
            p.push(format!("#{n} = {}", expr(g, s)));
            if !s.numbered.contains(&n) {
                s.numbered.push(n);
            }
        }
        1 => {
            let name = format!("_g{}", g.below(3));
            p.push(format!("#<{name}> = {}", expr(g, s)));
            if !s.globals.contains(&name) {
                s.globals.push(name);
            }
        }
        2 => {
            let name = format!("v{}", g.below(3));
            p.push(format!("#<{name}> = {}", expr(g, s)));
            if !s.locals.contains(&name) {
                s.locals.push(name);
            }
        }
        3 => {
            let axis = g.pick(&["X", "Y", "Z"]);
            let mode = g.pick(&["G0", "G1", "G1"]);
            p.push(format!(
                "{mode} {axis}{} F[ABS{}+1]",
                expr(g, s),
                expr(g, s)
            ));
        }
        4 => {
            let a = value(g, s, 1);
            let b = value(g, s, 1);
            p.push(format!("(DEBUG, a={a} b={b} x=#<_x>)"));
        }
        5 => {
            let l = p.label();
            p.push(format!("o{l} if [{} GT 0]", value(g, s, 1)));
            block(g, p, s, depth - 1, in_loop);
            if g.chance(40) {
                p.push(format!("o{l} elseif [{} LT 0]", value(g, s, 1)));
                block(g, p, s, depth - 1, in_loop);
            }
            if g.chance(50) {
                p.push(format!("o{l} else"));
                block(g, p, s, depth - 1, in_loop);
            }
            p.push(format!("o{l} endif"));
        }
        6 | 7 => {
            // a bounded while loop over its own counter
            let l = p.label();
            let c = format!("_c{l}");
            p.push(format!("#<{c}> = 0"));
            p.push(format!("o{l} while [#<{c}> LT {}]", g.below(4)));
            p.push(format!("#<{c}> = [#<{c}> + 1]"));
            s.globals.push(c);
            block(g, p, s, depth - 1, Some(l));
            p.push(format!("o{l} endwhile"));
        }
        8 => {
            let l = p.label();
            p.push(format!("o{l} repeat [{}]", g.below(3)));
            block(g, p, s, depth - 1, in_loop);
            p.push(format!("o{l} endrepeat"));
        }
        9 => {
            let l = p.label();
            let c = format!("_d{l}");
            p.push(format!("#<{c}> = 0"));
            p.push(format!("o{l} do"));
            p.push(format!("#<{c}> = [#<{c}> + 1]"));
            s.globals.push(c.clone());
            block(g, p, s, depth - 1, Some(l));
            p.push(format!("o{l} while [#<{c}> LT {}]", 1 + g.below(3)));
        }
        _ => match in_loop {
            Some(l) if g.chance(50) => {
                let kw = g.pick(&["break", "continue"]);
                let i = p.label();
                p.push(format!("o{i} if [{} GT 0]", value(g, s, 1)));
                p.push(format!("o{l} {kw}"));
                p.push(format!("o{i} endif"));
            }
            _ => {
                let sub = g.pick(&["<s1>", "<s2>"]);
                p.push(format!(
                    "o{sub} call [{}] [{}]",
                    value(g, s, 1),
                    value(g, s, 1)
                ));
                p.push("(DEBUG, returned=#<_value> #<_value_returned>)".into());
            }
        },
    }
}

fn block(g: &mut Gen, p: &mut Text, s: &mut Scope, depth: u32, in_loop: Option<u32>) {
    for _ in 0..1 + g.below(3) {
        statement(g, p, s, depth, in_loop);
    }
}

/// A whole program from `seed`: two subroutines, then the main body.
fn program(seed: u64) -> String {
    let mut g = Gen(seed | 1);
    let mut p = Text {
        lines: vec!["G21 G90 G94 F100".into()],
        label: 0,
    };
    for sub in ["s1", "s2"] {
        p.push(format!("o<{sub}> sub"));
        let mut s = Scope {
            numbered: vec![1, 2],
            globals: vec![],
            locals: vec![],
        };
        block(&mut g, &mut p, &mut s, 1, None);
        if g.chance(60) {
            // LinuxCNC evaluates a return value also while it reads the definition,
            // and then leaves an undefined named parameter's value uninitialised
            // (read_named_parameter returns early); softnc takes 0 (docs/gcode.md):
            // return values here read numbered parameters only
            let numbered = Scope {
                numbered: vec![1, 2],
                globals: vec![],
                locals: vec![],
            };
            p.push(format!("o<{sub}> return [{}]", value(&mut g, &numbered, 1)));
        }
        p.push(format!("o<{sub}> endsub"));
    }
    let mut s = Scope {
        numbered: vec![],
        globals: vec![],
        locals: vec![],
    };
    for _ in 0..2 + g.below(5) {
        statement(&mut g, &mut p, &mut s, 2, None);
    }
    p.push("M2".into());
    p.lines.join("\n") + "\n"
}

fn read(text: &str) -> Result<softnc_gcode::Program, GcodeError> {
    let options = ReadOptions {
        params: Some(softnc_gcode::Params::default()),
        parameters_in_inches: true,
        block_limit: Some(200_000),
        // probe moves read as rs274's stand-alone interpreter reads them
        probe_results: softnc_gcode::ProbeResults::StandIn,
        ..Default::default()
    };
    softnc_gcode::read_program_with(text, "fuzz.ngc", &profile(), &options).map(|(p, _)| p)
}

/// What `rs274` made of a program.
enum Lcnc {
    Accepted {
        /// End points (mm) and the mm per printed unit of each.
        moves: Vec<[f64; 3]>,
        units: Vec<f64>,
        messages: Vec<String>,
    },
    /// The text of the line it stopped on.
    Rejected(String),
    /// It ended without naming a line (killed by a signal, or no message): no
    /// verdict. Two rs274 running at once (another test, another user of the
    /// machine) crash with SIGBUS.
    NoVerdict,
}

fn rs274_available() -> bool {
    Command::new("rs274")
        .arg("-h")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

fn run_rs274(dir: &Path, text: &str) -> Lcnc {
    let ngc = dir.join("fuzz.ngc");
    let var = dir.join("empty.var");
    let out = dir.join("out.txt");
    std::fs::write(&ngc, text).unwrap();
    std::fs::write(&var, "").unwrap(); // rs274 writes its parameters back at exit
                                       // two rs274 at once crash one another (SIGBUS, seen here): one at a time
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let r = Command::new("rs274")
        .arg("-v")
        .arg(&var)
        .arg("-g")
        .arg(&ngc)
        .arg(&out)
        .current_dir(dir)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    if !r.status.success() {
        let err = String::from_utf8_lossy(&r.stderr);
        let last = err
            .trim_end()
            .lines()
            .last()
            .unwrap_or("")
            .trim()
            .to_string();
        if r.status.code().is_none() || last.is_empty() || last == "executing" {
            return Lcnc::NoVerdict;
        }
        return Lcnc::Rejected(last);
    }
    let printed = std::fs::read_to_string(&out).unwrap_or_default();
    let mut moves = Vec::new();
    let mut messages = Vec::new();
    let mut mm_per_unit = 1.0;
    let mut units = Vec::new();
    for l in printed.lines() {
        let Some(call) = l.split_whitespace().nth(2) else {
            continue;
        };
        if call.starts_with("USE_LENGTH_UNITS(") {
            mm_per_unit = if call.contains("INCHES") { 25.4 } else { 1.0 };
        }
        if call.starts_with("STRAIGHT_TRAVERSE(") || call.starts_with("STRAIGHT_FEED(") {
            let args = &l[l.find('(').unwrap() + 1..l.rfind(')').unwrap()];
            let v: Vec<f64> = args
                .split(',')
                .take(3)
                .map(|x| x.trim().parse().unwrap())
                .collect();
            moves.push([v[0], v[1], v[2]].map(|x| x * mm_per_unit));
            units.push(mm_per_unit);
        } else if call.starts_with("MESSAGE(") {
            let a = l.find("MESSAGE(\"").unwrap() + 9;
            let b = l.rfind("\")").unwrap();
            messages.push(l[a..b].to_string());
        }
    }
    Lcnc::Accepted {
        moves,
        units,
        messages,
    }
}

fn ours(p: &softnc_gcode::Program) -> (Vec<[f64; 3]>, Vec<String>) {
    let moves = p
        .motions
        .iter()
        .filter(|m| {
            matches!(
                m.kind,
                MotionKind::Traverse { .. } | MotionKind::Feed { .. }
            )
        })
        .map(|m| m.canon_view().0.unwrap().0)
        .collect();
    let messages = p
        .warnings
        .iter()
        .filter_map(|w| w.split_once(": debug: ").map(|(_, m)| m.to_string()))
        .collect();
    (moves, messages)
}

thread_local! {
    /// Counts for the summary line (per test): programs, accepted by both, moves,
    /// messages, no verdict.
    static STATS: [std::cell::Cell<usize>; 5] = Default::default();
}

fn count(k: usize, n: usize) {
    STATS.with(|s| s[k].set(s[k].get() + n));
}

fn check(text: &str, dir: Option<&Path>) -> Result<(), String> {
    let a = read(text);
    let b = read(text);
    match (&a, &b) {
        (Ok(x), Ok(y)) => {
            if x.motions != y.motions || x.warnings != y.warnings || x.blocks != y.blocks {
                return Err("two readings differ".into());
            }
        }
        (Err(x), Err(y)) if x == y => {}
        _ => return Err(format!("two readings differ: {a:?} / {b:?}")),
    }
    let Some(dir) = dir else { return Ok(()) };
    count(0, 1);
    let lines: Vec<&str> = text.lines().collect();
    match (run_rs274(dir, text), a) {
        (Lcnc::NoVerdict, _) => {
            count(4, 1);
            Ok(())
        }
        (_, Err(e)) if matches!(e.kind, softnc_gcode::ErrorKind::Unsupported { .. }) => {
            Err(format!("refused as unsupported: {e}"))
        }
        (Lcnc::Rejected(line), Ok(_)) => Err(format!("rs274 rejects at '{line}'; softnc reads it")),
        (Lcnc::Rejected(line), Err(e)) => {
            let ours = lines.get(e.line as usize - 1).map_or("", |l| l.trim());
            if ours == line {
                Ok(())
            } else {
                Err(format!("rs274 rejects at '{line}'; softnc: {e}"))
            }
        }
        (Lcnc::Accepted { .. }, Err(e)) => Err(format!("rs274 accepts; softnc: {e}")),
        (
            Lcnc::Accepted {
                moves,
                units,
                messages,
            },
            Ok(p),
        ) => {
            count(1, 1);
            count(2, moves.len());
            count(3, messages.len());
            let (m, d) = ours(&p);
            if !same_messages(&d, &messages) {
                return Err(format!("DEBUG: rs274 {messages:?}\nsoftnc {d:?}"));
            }
            if m.len() != moves.len() {
                return Err(format!("{} moves, rs274 {}", m.len(), moves.len()));
            }
            for (k, ((x, y), unit)) in m.iter().zip(&moves).zip(&units).enumerate() {
                // one printed unit: a tie at the fifth decimal may round either way
                if x.iter()
                    .zip(y)
                    .any(|(a, b)| (a - b).abs() > 1.5e-4 * unit + 1e-12 * b.abs())
                {
                    return Err(format!("move {k}: {x:?}, rs274 {y:?}"));
                }
            }
            Ok(())
        }
    }
}

/// The messages agree: exactly, or (a pre-release `rs274`) with numbers within
/// its 1e-4 of printing as 0.
fn same_messages(ours: &[String], lcnc: &[String]) -> bool {
    if SEMANTICS.get() == Semantics::Release {
        return ours == lcnc;
    }
    ours.len() == lcnc.len()
        && ours.iter().zip(lcnc).all(|(a, b)| {
            let (ta, tb): (Vec<&str>, Vec<&str>) = (
                a.split([' ', '=', '[', ']', '/']).collect(),
                b.split([' ', '=', '[', ']', '/']).collect(),
            );
            ta.len() == tb.len()
                && ta.iter().zip(&tb).all(|(x, y)| {
                    x == y
                        || matches!((x.parse::<f64>(), y.parse::<f64>()),
                            (Ok(p), Ok(q)) if (p - q).abs() < 1e-4 + 1e-9)
                })
        })
}

/// Ask `rs274` which comparison it makes: `[1.00001 EQ 1]` is 1 before 2.9.0.
fn probe_semantics(dir: &Path) -> Semantics {
    match run_rs274(dir, "#1=[1.00001 EQ 1]\n(DEBUG,#1)\nM2\n") {
        Lcnc::Accepted { messages, .. }
            if messages.first().map(String::as_str) == Some("1.000000") =>
        {
            Semantics::PreRelease
        }
        _ => Semantics::Release,
    }
}

/// Run `cases` programs from `make` through [`check`] and `extra`, against rs274
/// where it is installed (in a folder of its own, `tag`).
fn fuzz(tag: &str, make: fn(u64) -> String, extra: fn(&str) -> Result<(), String>) {
    let dir = if rs274_available() {
        let d = std::env::temp_dir().join(format!("softnc-diff-fuzz-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let sem = probe_semantics(&d);
        if sem == Semantics::PreRelease {
            eprintln!(
                "note: the installed rs274 predates LinuxCNC 2.9.0 (EQ within 1e-4, exact \
                 LE/GE): programs are drawn without EQ NE LE GE, DEBUG numbers compared \
                 within 1e-4"
            );
        }
        SEMANTICS.set(sem);
        Some(d)
    } else {
        eprintln!(
            "note: rs274 (LinuxCNC) is not installed: the random programs are only checked \
             to read without panic, twice identically, and consistently"
        );
        None
    };
    let cases = std::env::var("SOFTNC_DIFF_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(48);
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(&any::<u64>(), |seed| {
        let text = make(seed);
        check(&text, dir.as_deref())
            .and_then(|()| extra(&text))
            .map_err(|e| TestCaseError::fail(format!("{e}\n--- program (seed {seed}):\n{text}")))
    });
    if let Some(d) = &dir {
        std::fs::remove_dir_all(d).ok();
        let n = |k: usize| STATS.with(|s| s[k].get());
        eprintln!(
            "diff fuzz ({tag}) against rs274: {} programs, {} accepted by both ({} moves, \
             {} DEBUG messages compared), {} without a verdict from rs274 (it crashed or \
             named no line), the others rejected by both on the same line",
            n(0),
            n(1),
            n(2),
            n(3),
            n(4)
        );
    }
    if let Err(e) = result {
        panic!("{e}");
    }
}

#[test]
fn random_language_programs_read_as_rs274_reads_them() {
    fuzz("language", program, |_| Ok(()));
}

/// A program of work offsets, XY rotations, G92/G52, G28/G30, G53 and moves
/// (straight and G17 arcs), each line followed by a DEBUG of the machine position
/// (`#<_abs_x>` …) and the program point (#5420 …).
fn offsets_program(seed: u64) -> String {
    let mut g = Gen(seed | 1);
    let mut lines = vec![g.pick(&["G21", "G20"]).to_string(), "F100 G17".into()];
    let mut rotated = false;
    for _ in 0..4 + g.below(10) {
        let axes = |g: &mut Gen, p: u64| {
            let mut w = String::new();
            for a in ["X", "Y", "Z"] {
                if g.chance(p) {
                    w += &format!(" {a}{}", g.number());
                }
            }
            w
        };
        let l = match g.below(11) {
            0 | 1 => {
                let l = g.pick(&["L2", "L20"]);
                let mut w = format!("G10 {l} P{}{}", g.below(5), axes(&mut g, 60));
                if l == "L2" && g.chance(80) {
                    w += &format!(" R{}", g.below(361) as i64 - 180);
                    rotated = true;
                }
                w
            }
            2 => g.pick(&["G54", "G55", "G56", "G57"]).to_string(),
            3 => {
                let w = axes(&mut g, 60);
                format!(
                    "{}{}",
                    g.pick(&["G92", "G52"]),
                    if w.is_empty() { " X0".into() } else { w }
                )
            }
            4 => g
                .pick(&["G92.1", "G92.2", "G92.3", "G28.1", "G30.1"])
                .to_string(),
            5 => format!("{}{}", g.pick(&["G28", "G30"]), axes(&mut g, 30)),
            6 => format!("G53 {}{}", g.pick(&["G0", "G1"]), axes(&mut g, 60)),
            7 => {
                let (i, j) = (g.below(9) as i64 - 4, g.below(9) as i64 - 4);
                let (i, j) = if (i, j) == (0, 0) { (1, 0) } else { (i, j) };
                format!(
                    "G91 G{} X{} Y{} I{i} J{j}\nG90",
                    g.pick(&["2", "3"]),
                    2 * i,
                    2 * j
                )
            }
            // a probe move (rs274's stand-in results: the point after it backed off
            // its end) and what it left in #5061–#5063, #5070
            // (not once an XY rotation may be in force: rs274's stand-alone canon
            // then backs off from a start in a frame of its own bookkeeping)
            10 if !rotated => format!(
                "{}{}\n(DEBUG,#5061 #5062 #5063 #5070)",
                g.pick(&["G38.2", "G38.3", "G38.4", "G38.5"]),
                axes(&mut g, 60)
            ),
            _ => format!("{}{}", g.pick(&["G0", "G1"]), axes(&mut g, 70)),
        };
        for part in l.lines() {
            lines.push(part.to_string());
            lines.push("(DEBUG,#<_abs_x> #<_abs_y> #<_abs_z> #5420 #5421 #5422)".into());
        }
    }
    lines.push("M2".into());
    lines.join("\n") + "\n"
}

/// Each motion's `end + offset_mm` is the machine position LinuxCNC gives
/// (`#<_abs_x>` … in the DEBUG after its line, program units; compared with
/// rs274's by [`check`]).
fn machine_points_match(text: &str) -> Result<(), String> {
    let Ok(p) = read(text) else { return Ok(()) };
    let debug: std::collections::HashMap<u32, Vec<f64>> = p
        .warnings
        .iter()
        .filter_map(|w| {
            let (head, msg) = w.split_once(": debug: ")?;
            let line: u32 = head.rsplit(':').next()?.parse().ok()?;
            Some((
                line,
                msg.split_whitespace()
                    .filter_map(|x| x.parse().ok())
                    .collect(),
            ))
        })
        .collect();
    let mut last: std::collections::HashMap<u32, &softnc_gcode::Motion> = Default::default();
    // (a probe move ends where the machine stops, not at its end: its DEBUG
    // is compared as text with rs274's)
    for m in &p.motions {
        if !matches!(m.kind, MotionKind::Probe { .. }) {
            last.insert(m.line, m);
        }
    }
    for (line, m) in last {
        let (Some(end), Some(abs)) = (m.kind.end(), debug.get(&(line + 1))) else {
            continue;
        };
        let unit = if m.inch { 25.4 } else { 1.0 };
        let machine = end + m.offset_mm;
        for k in 0..3 {
            if (machine.0[k] - abs[k] * unit).abs() > 2e-3 {
                return Err(format!(
                    "line {line}: machine {:?}, #<_abs_x..z> {:?} ({})",
                    machine.0,
                    &abs[..3],
                    if m.inch { "in" } else { "mm" }
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn random_offset_and_rotation_programs_read_as_rs274_reads_them() {
    fuzz("offsets", offsets_program, machine_points_match);
}

/// A program of canned cycles (G73, G74, G81–G87, G89; tapping in G17 only) in a
/// random plane, unit, distance mode and retract mode, with their words often
/// missing or out of order, `L` repeats, polar words, bare positions that repeat
/// the cycle, G80, G0/G1 moves that end a series, path modes, feed changes,
/// spindle changes and XY rotations.
fn cycles_program(seed: u64) -> String {
    let mut g = Gen(seed | 1);
    let plane = g.pick(&["G17", "G17", "G18", "G19"]);
    // the plane's two axes, then its drilling axis
    let axes = match plane {
        "G17" => ["X", "Y", "Z"],
        "G18" => ["Z", "X", "Y"],
        _ => ["Y", "Z", "X"],
    };
    let mut lines = vec![
        format!("{} G90 G94 F200 S1000 M3", g.pick(&["G21", "G21", "G20"])),
        format!("G0 X{} Y{} Z{}", g.number(), g.number(), g.number()),
        plane.to_string(),
    ];
    let mut codes = vec!["G81", "G82", "G83", "G73", "G85", "G86", "G87", "G89"];
    if plane == "G17" {
        codes.extend(["G84", "G74"]);
    }
    for _ in 0..1 + g.below(12) {
        let l = match g.below(20) {
            0..=6 => {
                let code = g.pick(&codes);
                let mut w = vec![code.to_string()];
                for (k, a) in axes.iter().enumerate() {
                    if k < 2 && g.chance(80) {
                        w.push(format!("{a}{}", g.number()));
                    }
                    if k == 2 && g.chance(90) {
                        // the bottom, mostly below R
                        w.push(format!("{a}{}", g.below(120) as f64 / 10.0 - 10.0));
                    }
                }
                if g.chance(90) {
                    w.push(format!("R{}", g.below(100) as f64 / 10.0 - 2.0));
                }
                if matches!(code, "G82" | "G86" | "G89" | "G84" | "G74") && g.chance(90) {
                    w.push(format!("P{}", g.below(10) as f64 / 10.0));
                }
                if matches!(code, "G83" | "G73") && g.chance(90) {
                    w.push(format!("Q{}", g.below(30) as f64 / 10.0 + 0.1));
                }
                if code == "G87" {
                    for l in ["I", "J", "K"] {
                        if g.chance(90) {
                            w.push(format!("{l}{}", g.below(60) as f64 / 10.0 - 3.0));
                        }
                    }
                }
                if g.chance(20) {
                    w.push(format!("L{}", g.below(5)));
                }
                if plane == "G17" && g.chance(10) {
                    w.retain(|x| !x.starts_with('X') && !x.starts_with('Y'));
                    w.push(format!("@{}", g.below(200) as f64 / 10.0 + 1.0));
                    w.push(format!("^{}", g.below(360) as i64 - 180));
                }
                // the words in any order after the code
                for k in (2..w.len()).rev() {
                    w.swap(k, 1 + g.below(k as u64) as usize);
                }
                w.join(" ")
            }
            7..=10 => {
                let mut w = String::new();
                for a in ["X", "Y", "Z"] {
                    if g.chance(50) {
                        w += &format!("{a}{} ", g.number());
                    }
                }
                if w.is_empty() {
                    "X1".into()
                } else {
                    w.trim_end().to_string()
                }
            }
            11 => g.pick(&["G90", "G91"]).into(),
            12 => g.pick(&["G98", "G99"]).into(),
            13 => "G80".into(),
            14 => format!("G0 Z{}", g.number()),
            15 => format!("G1 X{} Z{}", g.number(), g.number()),
            16 => g.pick(&["G61", "G64", "G61.1", "G64 P0.1"]).into(),
            17 => format!("F{}", 50 + g.below(450)),
            18 => g
                .pick(&["G10 L2 P1 R30", "G10 L2 P1 R0", "G10 L2 P1 R-45"])
                .into(),
            _ => g.pick(&["M5", "M3", "M4"]).into(),
        };
        lines.push(l);
    }
    lines.push("M2".into());
    lines.join("\n") + "\n"
}

#[test]
fn random_canned_cycle_programs_read_as_rs274_reads_them() {
    fuzz("cycles", cycles_program, |_| Ok(()));
}

/// A program of cutter radius compensation: profiles of random lines, arcs (R and
/// centre format, either direction) and rapids in G17 or G18, mm or inch, with the
/// tool table's diameter (G41/G42 with or without D, after a tool change) or one
/// given (G41.1/G42.1, negative ones too), moves along the normal axis alone,
/// incremental stretches, feed changes, dwells and coolant held behind the moves,
/// exits (G40) and second passes. Many end in one of LinuxCNC's errors (a gouge,
/// a concave corner the tool does not fit, an arc smaller than the tool): both
/// readers must then stop on the same line.
#[allow(clippy::too_many_lines)]
fn comp_program(seed: u64) -> String {
    let mut g = Gen(seed | 1);
    let g18 = g.chance(25);
    // the plane's first and second axis, its normal, and the centre words of each
    let (a, b, n, ia, ib) = if g18 {
        ("Z", "X", "Y", "K", "I")
    } else {
        ("X", "Y", "Z", "I", "J")
    };
    let inch = g.chance(15);
    let scale = if inch { 0.1 } else { 1.0 };
    let num = |g: &mut Gen, span: f64| -> f64 {
        ((g.below(2001) as f64 / 1000.0 - 1.0) * span * scale * 100.0).round() / 100.0
    };
    let mut lines = vec![
        format!(
            "{} G90 G94 {} F300 S1000 M3",
            if inch { "G20" } else { "G21" },
            if g18 { "G18" } else { "G17" }
        ),
        "T1 M6".to_string(),
    ];
    let (mut pa, mut pb) = (num(&mut g, 30.0), num(&mut g, 30.0));
    lines.push(format!("G0 {a}{pa} {b}{pb} {n}1"));
    lines.push(format!("G1 {n}-1"));
    for _pass in 0..1 + g.below(2) {
        let on = match g.below(8) {
            0 => "G41".to_string(),
            1 => "G42 D1".to_string(),
            2 => "G41 D2".to_string(),
            3 => "G42 D3".to_string(),
            4 => format!("G41.1 D{}", (1 + g.below(40)) as f64 / 10.0 * scale),
            5 => format!("G42.1 D{}", (1 + g.below(40)) as f64 / 10.0 * scale),
            6 => format!("G41.1 D-{}", (1 + g.below(30)) as f64 / 10.0 * scale),
            _ => "G41 D1".to_string(),
        };
        lines.push(on);
        let mut absolute = true;
        for _ in 0..2 + g.below(10) {
            let (ea, eb) = (num(&mut g, 30.0), num(&mut g, 30.0));
            let (wa, wb) = if absolute {
                (ea, eb)
            } else {
                (ea - pa, eb - pb)
            };
            let fmt = |v: f64| {
                format!("{v:.4}")
                    .trim_end_matches('0')
                    .trim_end_matches('.')
                    .to_string()
            };
            let l = match g.below(20) {
                0..=7 => format!("G1 {a}{} {b}{}", fmt(wa), fmt(wb)),
                8..=10 => {
                    // R format: at least half the chord, either sign
                    let chord = (ea - pa).hypot(eb - pb);
                    if chord < 1e-3 {
                        continue;
                    }
                    let r = chord / 2.0 * (1.0 + g.below(300) as f64 / 100.0);
                    let r = if g.chance(30) { -r } else { r };
                    format!(
                        "{} {a}{} {b}{} R{}",
                        g.pick(&["G2", "G3"]),
                        fmt(wa),
                        fmt(wb),
                        fmt(r)
                    )
                }
                11..=13 => {
                    // centre format: a centre, the end on its circle
                    let (ca, cb) = (num(&mut g, 15.0), num(&mut g, 15.0));
                    let r = ca.hypot(cb);
                    if r < 1e-3 {
                        continue;
                    }
                    let t = g.below(628) as f64 / 100.0;
                    let (xa, xb) = (pa + ca + r * t.cos(), pb + cb + r * t.sin());
                    let (xa, xb) = (
                        (xa * 10_000.0).round() / 10_000.0,
                        (xb * 10_000.0).round() / 10_000.0,
                    );
                    let (wa, wb) = if absolute {
                        (xa, xb)
                    } else {
                        (xa - pa, xb - pb)
                    };
                    let line = format!(
                        "{} {a}{} {b}{} {ia}{} {ib}{}",
                        g.pick(&["G2", "G3"]),
                        fmt(wa),
                        fmt(wb),
                        fmt(ca),
                        fmt(cb)
                    );
                    lines.push(line);
                    pa = xa;
                    pb = xb;
                    continue;
                }
                14 => format!("G0 {a}{} {b}{}", fmt(wa), fmt(wb)),
                15 => {
                    lines.push(format!("G1 {n}{}", fmt(num(&mut g, 2.0))));
                    continue;
                }
                16 => {
                    absolute = !absolute;
                    lines.push(if absolute { "G90" } else { "G91" }.into());
                    continue;
                }
                17 => {
                    lines.push(g.pick(&["G4 P0.1", "M8", "M9", "F500", "S2000"]).into());
                    continue;
                }
                _ => format!("{a}{} {b}{}", fmt(wa), fmt(wb)),
            };
            lines.push(l);
            pa = ea;
            pb = eb;
        }
        if !absolute {
            lines.push("G90".into());
        }
        let (xa, xb) = (num(&mut g, 40.0), num(&mut g, 40.0));
        lines.push(format!("G40 G1 {a}{xa} {b}{xb}"));
        pa = xa;
        pb = xb;
    }
    lines.push("M2".into());
    lines.join("\n") + "\n"
}

/// The arcs of a compensated program as rs274 prints them (end, centre, turns),
/// against softnc's, where rs274 is installed and both read the program whole.
fn comp_arcs_match(text: &str) -> Result<(), String> {
    if !rs274_available() {
        return Ok(());
    }
    let Ok(p) = read(text) else { return Ok(()) };
    let dir =
        std::env::temp_dir().join(format!("softnc-diff-fuzz-comp-arcs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ngc = dir.join("fuzz.ngc");
    let var = dir.join("empty.var");
    let out = dir.join("out.txt");
    std::fs::write(&ngc, text).unwrap();
    std::fs::write(&var, "").unwrap();
    let r = Command::new("rs274")
        .arg("-v")
        .arg(&var)
        .arg("-g")
        .arg(&ngc)
        .arg(&out)
        .current_dir(&dir)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let printed = std::fs::read_to_string(&out).unwrap_or_default();
    std::fs::remove_dir_all(&dir).ok();
    if !r.status.success() {
        return Ok(());
    }
    let mut theirs = Vec::new();
    for l in printed.lines() {
        if l.split_whitespace()
            .nth(2)
            .is_some_and(|c| c.starts_with("ARC_FEED("))
        {
            let args = &l[l.find('(').unwrap() + 1..l.rfind(')').unwrap()];
            let v: Vec<f64> = args
                .split(',')
                .take(6)
                .map(|x| x.trim().parse().unwrap())
                .collect();
            theirs.push(v);
        }
    }
    let ours: Vec<Vec<f64>> = p
        .motions
        .iter()
        .filter_map(|m| match m.kind {
            MotionKind::Arc { plane, turns, .. } => {
                let (e, c) = (m.canon_end, m.canon_center);
                let (a, b, n) = plane.axes();
                Some(vec![e[a], e[b], c[a], c[b], f64::from(turns), e[n]])
            }
            _ => None,
        })
        .collect();
    if ours.len() != theirs.len() {
        return Err(format!("{} arcs, rs274 {}", ours.len(), theirs.len()));
    }
    for (k, (x, y)) in ours.iter().zip(&theirs).enumerate() {
        // (program units: one printed unit, a tie either way)
        if x.iter()
            .zip(y)
            .any(|(a, b)| (a - b).abs() > 1.5e-4 + 1e-12 * b.abs())
        {
            return Err(format!("arc {k}: {x:?}, rs274 {y:?}"));
        }
    }
    Ok(())
}

#[test]
fn random_compensated_programs_read_as_rs274_reads_them() {
    fuzz("comp", comp_program, comp_arcs_match);
}

#[test]
fn the_generator_makes_programs_that_use_the_language() {
    // the programs are not trivial: loops run, subroutines are called, values are
    // printed (checked without rs274)
    let mut looped = 0;
    let mut called = 0;
    for seed in 0..200u64 {
        let text = program(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        if let Ok(p) = read(&text) {
            if p.blocks > text.lines().count() {
                looped += 1;
            }
            if p.warnings.iter().any(|w| w.contains("returned=")) {
                called += 1;
            }
        }
    }
    assert!(
        looped > 20 && called > 20,
        "looped {looped}, called {called}"
    );
    // the cycle programs drill: most read whole with cycle motions in exact path
    let mut drilled = 0;
    for seed in 0..200u64 {
        let text = cycles_program(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        if let Ok(p) = read(&text) {
            drilled += usize::from(
                p.motions
                    .iter()
                    .any(|m| m.path_mode == softnc_gcode::PathMode::ExactStop),
            );
        }
    }
    assert!(drilled > 40, "{drilled} of 200 cycle programs drilled");
    // the compensated programs cut: many read whole with arcs (corners and the
    // program's), others stop on one of LinuxCNC's compensation errors
    let (mut whole, mut stopped) = (0, 0);
    for seed in 0..200u64 {
        let text = comp_program(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        match read(&text) {
            Ok(p) => {
                whole += usize::from(
                    p.motions
                        .iter()
                        .any(|m| matches!(m.kind, MotionKind::Arc { .. })),
                )
            }
            Err(e) => {
                stopped += usize::from(!matches!(
                    e.kind,
                    softnc_gcode::ErrorKind::Unsupported { .. }
                ))
            }
        }
    }
    assert!(
        whole > 40 && stopped > 20,
        "{whole} read whole with arcs, {stopped} stopped, of 200"
    );
}
