//! A streamed plan (`check_program`, `stream_program`) gives the figures, the first
//! error and the samples of the whole plan (`read_and_plan`, `Plan::interpolator`)
//! bit for bit while the producer keeps up; when it does not, the path brakes within
//! its limits to what it has and says it starved.

use super::common;
use common::{limit_ratios, profile};
use softnc_core::{FeedProfile, MotionProfile};
use softnc_gcode::Program;
use softnc_planner::{
    check_and_stream, check_program, check_program_parallel, read_and_plan, stream_program,
    CheckedProgram, PlanOptions, ReadPlanError, Sample, StreamMode,
};
use std::fmt::Write;
use std::sync::Arc;

/// Check and stream `text`; compare with the whole plan. `limit`: compare only the
/// first so many samples (None: all). Returns false if the whole plan refuses it.
fn same_as_whole(text: &str, file: &str, p: &MotionProfile, limit: Option<usize>) -> bool {
    let opts = PlanOptions {
        ignore_soft_limits: true,
        ..Default::default()
    };
    let whole = read_and_plan(text, file, p, &opts);
    let checked = check_program(text, file, p, &opts);
    let key = |r: &Result<(Program, CheckedProgram), ReadPlanError>| {
        r.as_ref()
            .map(|(p, c)| (p.blocks, p.warnings.clone(), c.clone()))
            .map_err(|e| e.clone())
    };
    assert_eq!(
        key(&check_program_parallel(text, file, p, &opts)),
        key(&checked),
        "{file}: on two threads"
    );
    let (want_prog, plan) = match whole {
        Err(e) => {
            assert_eq!(checked.unwrap_err(), e, "{file}: the first error");
            return false;
        }
        Ok(w) => w,
    };
    let (prog, checked) = checked.unwrap_or_else(|e| panic!("{file}: check refused: {e}"));
    assert_eq!(prog.blocks, want_prog.blocks, "{file}");
    assert_eq!(prog.warnings, want_prog.warnings, "{file}");
    assert_eq!(checked.stats(), plan.stats(), "{file}: figures");
    assert_eq!(checked.motions(), plan.motions(), "{file}");
    assert_eq!(checked.elements(), plan.elements(), "{file}");
    assert_eq!(checked.spindle_changes(), plan.spindle_changes(), "{file}");
    let n = limit.unwrap_or(usize::MAX);
    let (again, (mismatch, count, starved)) = check_and_stream(text, file, p, &opts, |it| {
        let mut whole = plan.interpolator();
        let mut count = 0usize;
        let mut mismatch = None;
        for (k, s) in it.by_ref().take(n).enumerate() {
            let w = whole.next();
            if w != Some(s) && mismatch.is_none() {
                mismatch = Some((k, w, s));
            }
            count += 1;
        }
        if limit.is_none() && whole.next().is_some() && mismatch.is_none() {
            mismatch = Some((count, None, Sample::default()));
        }
        (mismatch, count, it.starved())
    })
    .unwrap();
    assert_eq!(again, checked);
    assert_eq!(starved, 0, "{file}: the offline stream never starves");
    assert!(
        mismatch.is_none(),
        "{file}: sample differs (index, whole, streamed): {mismatch:?}"
    );
    if limit.is_none() {
        assert_eq!(count as u64, plan.interpolator().count() as u64);
    }
    true
}

/// Lines, arcs in both formats, dwells, exact stops, blends, spindle changes and
/// G64 Q merging: several chunks of motions and many windows' worth of elements.
fn program(n: usize) -> String {
    let mut s =
        String::from("G21 G90 G17 G64 P0.02\nG0 X0 Y0 Z1\nG4 P0.1\nM3 S1000\nG1 Z-1 F900\n");
    let mut x = 0.0;
    for i in 0..n {
        match i % 7 {
            0 => writeln!(s, "G1 X{:.4} Y{:.4}", x + 0.7, (i % 5) as f64 * 0.1).unwrap(),
            1 => writeln!(s, "G1 X{:.4} Y0.3", x + 1.2).unwrap(),
            2 => writeln!(s, "G2 X{:.4} Y0.3 I0.25 J0", x + 1.7).unwrap(),
            3 => writeln!(s, "G3 X{:.4} Y0.3 R0.25 F1200", x + 2.2).unwrap(),
            4 if i % 70 == 4 => {
                writeln!(s, "G61 G1 Y1\nG4 P0.05\nM3 S{}\nG64 G1 Y0.3", 1000 + i).unwrap()
            }
            4 if i % 70 == 11 => writeln!(
                s,
                "G64 P0.01 Q0.005\nG1 X{:.4} Y0.301\nG1 X{:.4} Y0.299\nG1 X{:.4} Y0.3\nG64 P0.02",
                x + 2.3,
                x + 2.35,
                x + 2.4
            )
            .unwrap(),
            5 => writeln!(s, "G1 X{:.4} Y0.3 F{}", x + 2.45, 600 + (i % 13) * 300).unwrap(),
            _ => writeln!(s, "G0 X{:.4}", x + 2.5).unwrap(),
        }
        if i % 7 == 6 {
            x += 2.5;
            if x > 200.0 {
                x = 0.0;
                s.push_str("G0 Z1\nG0 X0\nG1 Z-1\n");
            }
        }
    }
    s.push_str("M2\n");
    s
}

/// Dense CAM polylines (many short elements within the braking distance: the window
/// and the lookahead's reach matter).
fn dense_circles(n: usize) -> String {
    let mut s = String::from("G21 G90 G64 P0.005\nG0 X20 Y0\nG1 F6000\n");
    for i in 1..=n {
        let a = i as f64 * std::f64::consts::TAU / 2000.0;
        writeln!(s, "G1 X{:.5} Y{:.5}", 20.0 * a.cos(), 20.0 * a.sin()).unwrap();
    }
    s.push_str("M2\n");
    s
}

/// Lines merged under G64 Q, arcs into and out of them (the arc after a chain comes
/// while the chain is flushed), pauses, dwells and exact stops between: with
/// `arc_blends` the reading thread of `check_program_parallel` works out the arcs'
/// data for the blends ([`softnc_planner`]'s `ArcPrep`), which must reach the arc
/// they belong to and no other move.
fn arcs_among_chains(n: usize) -> String {
    let mut s = String::from("G21 G90 G17 G64 P0.02 Q0.01\nG0 X0 Y0 Z1\nG1 Z0 F900\n");
    let mut x = 0.0;
    for i in 0..n {
        for k in 1..=4 {
            writeln!(
                s,
                "G1 X{:.4} Y{:.4}",
                x + 0.2 * k as f64,
                0.001 * (k % 2) as f64
            )
            .unwrap();
        }
        x += 0.8;
        let dir = if i % 2 == 0 { "G2" } else { "G3" };
        writeln!(s, "{dir} X{:.4} Y0 R0.25", x + 0.5).unwrap();
        x += 0.5;
        match i % 7 {
            2 => s.push_str("G4 P0.01\n"),
            4 => s.push_str("M0\n"),
            5 => s.push_str("G61\nG1 Y0.1\nG1 Y0\nG64 P0.02 Q0.01\n"),
            _ => {}
        }
        writeln!(s, "G3 X{:.4} Y0 I0.25 J0", x + 0.5).unwrap();
        x += 0.5;
    }
    s.push_str("M2\n");
    s
}

#[test]
fn arc_data_reach_their_arcs_on_two_threads() {
    for arc_blends in [false, true] {
        let mut p = profile(FeedProfile::Trapezoidal);
        p.planner.arc_blends = arc_blends;
        p.axes[0].max_mm = 1e6;
        assert!(same_as_whole(&arcs_among_chains(400), "q.ngc", &p, None));
    }
}

#[test]
fn streamed_plan_is_the_whole_plan() {
    // the two feed profiles side by side (one of the longest tests of the suite)
    std::thread::scope(|scope| {
        for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
            scope.spawn(move || streamed_plan_is_the_whole_plan_in(fp));
        }
    });
}

fn streamed_plan_is_the_whole_plan_in(fp: FeedProfile) {
    {
        let p = profile(fp);
        assert!(same_as_whole(&program(3000), "t.ngc", &p, None));
        assert!(same_as_whole(&dense_circles(30_000), "c.ngc", &p, None));
        assert!(same_as_whole("G21\nM2\n", "empty.ngc", &p, None));
        assert!(same_as_whole("G21\nG4 P0.2\nM2\n", "dwell.ngc", &p, None));
        assert!(same_as_whole("G21\nG0 X0\nM2\n", "nothing.ngc", &p, None));
        // refused (no program end): the same error
        assert!(!same_as_whole(
            "G0 X10\nG1 X20 F600\n",
            "short.ngc",
            &p,
            None
        ));
    }
}

/// Every machine profile of `config/machines` (acc/dec after interpolation, other
/// cycles and limits), and the default one with arc blends (fillets, trimmed arcs) in
/// both feed profiles.
#[test]
fn streamed_plan_is_the_whole_plan_on_every_profile() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
    let mut profiles = vec![];
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let path = e.path();
        if path.extension().is_some_and(|x| x == "ron") {
            profiles.push(MotionProfile::load(&path).unwrap());
        }
    }
    assert!(profiles.len() >= 2);
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let mut p = profile(fp);
        p.planner.arc_blends = true;
        profiles.push(p);
    }
    let texts = [program(1500), dense_circles(6000)];
    for p in &profiles {
        for t in &texts {
            assert!(same_as_whole(t, "p.ngc", p, None));
        }
    }
}

#[test]
fn errors_are_the_whole_plans() {
    // with arc blends the reading thread of `check_program_parallel` checks the
    // motions, without them the planning thread does
    for arc_blends in [false, true] {
        let mut p = profile(FeedProfile::Trapezoidal);
        p.planner.arc_blends = arc_blends;
        errors_are_the_whole_plans_on(&p);
    }
}

fn errors_are_the_whole_plans_on(p: &MotionProfile) {
    let p = p.clone();
    let opts = PlanOptions::default();
    let mut text = String::from("G21 G90\nG0 X-5000\n");
    for i in 0..5000 {
        writeln!(text, "G1 X{} F1000", i % 100).unwrap();
    }
    for t in [format!("{text}G1 X1 Y2 X3\nM2\n"), format!("{text}M2\n")] {
        let want = read_and_plan(&t, "e.ngc", &p, &opts).unwrap_err();
        assert_eq!(check_program(&t, "e.ngc", &p, &opts).unwrap_err(), want);
        assert_eq!(
            check_program_parallel(&t, "e.ngc", &p, &opts).unwrap_err(),
            want
        );
        assert_eq!(
            check_and_stream(&t, "e.ngc", &p, &opts, |_| ()).unwrap_err(),
            want
        );
    }
}

/// Every file of the shared corpus (`../shared/gcode`) that plans: the same figures,
/// errors and samples (the first 300,000 samples of each in this debug-built test;
/// `examples/stream_corpus.rs` compares whole streams in a release build).
#[test]
fn shared_corpus_streams_as_planned() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/gcode");
    if !root.is_dir() {
        // past the test harness's capture: a run without the corpus says so
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: shared_corpus_streams_as_planned: no corpus at {}",
            root.display()
        );
        return;
    }
    let mut files = vec![];
    let mut dirs = vec![root];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let path = e.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path
                .extension()
                .is_some_and(|x| x == "ngc" || x == "nc" || x == "gcode" || x == "txt")
            {
                files.push(path);
            }
        }
    }
    files.sort();
    for (fp, limit) in [
        (FeedProfile::Trapezoidal, 300_000),
        (FeedProfile::SCurve, 100_000),
    ] {
        let p = profile(fp);
        // the files shared out over the machine's cores (the longest test of the suite)
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
        let planned: usize = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|k| {
                    let (files, p) = (&files, &p);
                    scope.spawn(move || {
                        files
                            .iter()
                            .skip(k)
                            .step_by(threads)
                            .filter(|f| {
                                let text = String::from_utf8_lossy(&std::fs::read(f).unwrap())
                                    .into_owned();
                                same_as_whole(&text, &f.display().to_string(), p, Some(limit))
                            })
                            .count()
                    })
                })
                .collect();
            workers.into_iter().map(|w| w.join().unwrap()).sum()
        });
        eprintln!(
            "{fp:?}: {planned} of {} corpus files planned and streamed",
            files.len()
        );
        assert!(planned > 100, "only {planned} files planned");
    }
}

/// A real-time stream whose producer starts late and then trickles: the interpolator
/// waits at the start, brakes to the end of what it has whenever the lookahead runs
/// out, never passes a limit, and still ends exactly at the program's end.
#[test]
fn starved_stream_brakes_within_limits() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let opts = PlanOptions::default();
        let text = dense_circles(12_000);
        let (_, checked) = check_program(&text, "c.ngc", &p, &opts).unwrap();
        let plan = read_and_plan(&text, "c.ngc", &p, &opts).unwrap().1;
        let (producer, mut it) = stream_program(
            Arc::from(text.as_str()),
            "c.ngc",
            &p,
            &opts,
            &checked,
            StreamMode::RealTime,
        );
        // no element yet: the start, again, counted
        let first = it.next().unwrap();
        assert_eq!(first.pos_mm, plan.interpolator().next().unwrap().pos_mm);
        assert!(it.starved() > 0);
        let samples: Vec<Sample> = std::thread::scope(|scope| {
            let produced = scope.spawn(move || producer.run());
            let mut out = vec![];
            for s in it.by_ref() {
                out.push(s);
                if out.len() % 64 == 0 {
                    // a slow consumer now and then lets the producer catch up
                    std::thread::yield_now();
                }
                assert!(out.len() < 10_000_000, "never ends");
            }
            produced.join().unwrap().unwrap();
            out
        });
        assert!(it.is_finished() && !it.failed());
        eprintln!(
            "{fp:?}: starved {} times, {} samples (whole plan {})",
            it.starved(),
            samples.len(),
            plan.stats().samples
        );
        let r = limit_ratios(&samples, &p);
        assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{fp:?}: {r:?}");
        if fp == FeedProfile::SCurve {
            assert!(r[2] <= 1.0 + 1e-9, "{fp:?}: jerk {r:?}");
        }
        let end = plan.interpolator().last().unwrap().pos_mm;
        assert_eq!(samples.last().unwrap().pos_mm, end);
        // every sample on the programmed polyline's path (within the tolerance)
        let whole: Vec<Sample> = plan.interpolator().collect();
        assert!(samples.len() >= whole.len());
    }
}

/// A producer that fails half-way (a G-code error the check did not see: the file
/// changed): the interpolator stops within its limits at the end of what it got,
/// says so, and never finishes.
#[test]
fn failed_stream_stops_at_what_it_has() {
    let p = profile(FeedProfile::Trapezoidal);
    let opts = PlanOptions::default();
    let good = dense_circles(6_000);
    let (_, checked) = check_program(&good, "c.ngc", &p, &opts).unwrap();
    let bad = good.replace("M2\n", "G1 X1 Y2 X3\nM2\n");
    let (producer, mut it) = stream_program(
        Arc::from(bad.as_str()),
        "c.ngc",
        &p,
        &opts,
        &checked,
        StreamMode::Offline,
    );
    let samples: Vec<Sample> = std::thread::scope(|scope| {
        let produced = scope.spawn(move || producer.run());
        it.fill();
        let mut out = vec![];
        let mut still = 0;
        while still < 100 {
            let s = it.next().unwrap();
            if out.last().is_some_and(|l: &Sample| l.pos_mm == s.pos_mm) {
                still += 1;
            } else {
                still = 0;
            }
            out.push(s);
            assert!(out.len() < 1_000_000, "never stops");
        }
        assert!(produced.join().unwrap().is_err());
        out
    });
    assert!(it.failed() && !it.is_finished());
    let r = limit_ratios(&samples, &p);
    assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{r:?}");
}

/// Before any element has come, the first sample is where the path starts (short
/// programs too, whose elements the S-curve stage holds until the end).
#[test]
fn unfilled_stream_starts_where_the_path_starts() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        // the machine is not at the origin
        let opts = PlanOptions {
            start_mm: Some([7.0, -3.0, 1.0]),
            ..Default::default()
        };
        for text in [
            "G21 G90\nG0 X10 Y5\nG1 X20 F600\nM2\n",
            "G21 G90\nG4 P0.5\nG0 X-3 Y2 Z-1\nM2\n",
            dense_circles(50).as_str(),
        ] {
            let (_, checked) = check_program(text, "s.ngc", &p, &opts).unwrap();
            let plan = read_and_plan(text, "s.ngc", &p, &opts).unwrap().1;
            let (producer, mut it) = stream_program(
                Arc::from(text),
                "s.ngc",
                &p,
                &opts,
                &checked,
                StreamMode::RealTime,
            );
            let first = it.next().unwrap();
            assert_eq!(first.pos_mm, softnc_core::Vec3::new(7.0, -3.0, 1.0));
            assert_eq!(first, plan.interpolator().next().unwrap(), "{fp:?} {text}");
            assert_eq!(it.starved(), 1);
            drop(producer);
        }
    }
}
