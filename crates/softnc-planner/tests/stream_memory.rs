//! Memory of a streamed plan, measured by a counting global allocator: the peak heap
//! while checking and streaming a long straight-line program is bounded by the window,
//! not the program (the whole plan's grows with it); pulling samples from the
//! streamed interpolator allocates nothing.
//!
//! One test only: the byte counters are global, so nothing else may run beside it.

mod common;
use common::profile;
use softnc_core::FeedProfile;
use softnc_planner::{
    check_program, read_and_plan, stream_program, PlanOptions, Sample, StreamMode,
};
use std::fmt::Write;
use std::sync::Arc;

use softnc_test_support::{allocations as allocs, peak_of, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

const MB: f64 = 1024.0 * 1024.0;

#[test]
fn streaming_memory_is_bounded_by_the_window() {
    // 500,000 straight lines of 0.5 mm along X at the axes' top speed
    let lines = 500_000;
    let mut text = String::with_capacity(lines * 24);
    text.push_str("G21 G90 G64 P0.01\nG0 X0 Y0\nG1 F24000\n");
    for i in 1..=lines {
        writeln!(text, "G1 X{:.1} Y{}", i as f64 * 0.5, i % 2).unwrap();
    }
    text.push_str("M2\n");
    let text: Arc<str> = Arc::from(text.as_str());
    let p = profile(FeedProfile::Trapezoidal);
    let opts = PlanOptions {
        ignore_soft_limits: true,
        ..Default::default()
    };

    // the whole plan: read_and_plan, then pull every sample
    let ((whole_samples, whole_last, whole_stats), whole_peak) = peak_of(|| {
        let (_, plan) = read_and_plan(&text, "long.ngc", &p, &opts).unwrap();
        let mut n = 0u64;
        let mut last = Sample::default();
        for s in plan.interpolator() {
            n += 1;
            last = s;
        }
        (n, last, plan.stats())
    });

    // the check before motion
    let ((_, checked), check_peak) =
        peak_of(|| check_program(&text, "long.ngc", &p, &opts).unwrap());
    assert_eq!(checked.stats(), whole_stats);

    // the stream: producer thread, real-time consumer on this thread
    let ((n, last, consumer_allocs, starved), stream_peak) = peak_of(|| {
        let (producer, mut it) = stream_program(
            text.clone(),
            "long.ngc",
            &p,
            &opts,
            &checked,
            StreamMode::RealTime,
        );
        std::thread::scope(|scope| {
            let produced = scope.spawn(move || producer.run());
            it.fill();
            let before = allocs();
            let mut n = 0u64;
            let mut last = Sample::default();
            while let Some(s) = it.next() {
                n += 1;
                last = s;
                if n == 1000 {
                    it.set_feed_override(1.5);
                } else if n == 200_000 {
                    it.set_feed_override(0.7);
                }
            }
            let consumer_allocs = allocs() - before;
            produced.join().unwrap().unwrap();
            (n, last, consumer_allocs, it.starved())
        })
    });
    let window_bytes = softnc_planner::stream::stream_window_segments(&opts)
        * softnc_planner::stream::window_element_bytes();
    println!(
        "{lines} lines, {:.1} MB of text, {} elements: peak heap above the text: whole plan \
         {:.1} MB, check {:.2} MB, stream {:.2} MB (window {:.2} MB); {n} samples streamed \
         ({whole_samples} whole), {starved} starved, {consumer_allocs} allocations while pulling",
        text.len() as f64 / MB,
        checked.elements(),
        whole_peak as f64 / MB,
        check_peak as f64 / MB,
        stream_peak as f64 / MB,
        window_bytes as f64 / MB,
    );
    assert_eq!(consumer_allocs, 0, "pulling samples allocates nothing");
    assert_eq!(
        last.pos_mm, whole_last.pos_mm,
        "the stream ends where the plan does"
    );
    // the whole plan holds every element; the stream its window and the queue
    assert!(whole_peak > 50 * lines, "whole plan {whole_peak} B");
    assert!(
        stream_peak < window_bytes + 4 * 1024 * 1024,
        "stream {stream_peak} B, window {window_bytes} B"
    );
    assert!(check_peak < 4 * 1024 * 1024, "check {check_peak} B");
}
