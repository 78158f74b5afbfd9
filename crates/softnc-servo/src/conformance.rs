//! What every [`ServoBackend`] must do, written once and run by each backend crate
//! against itself (as iceoryx2 runs one suite against every implementation):
//!
//! ```ignore
//! #[test]
//! fn my_drive_conforms() {
//!     let profile = softnc_machine::MachineProfile::load("config/machines/default.ron".as_ref()).unwrap();
//!     softnc_servo::conformance::run("my-drive", &profile, &|| MyDrive::open(...));
//! }
//! ```
//!
//! Each check panics with the backend's name and what it did wrong. A simulated
//! backend (or any that claims to be deterministic) also runs [`deterministic`].

use crate::backend::{CommandMode, ServoBackend, MAX_AXES};
use crate::engine::CycleEngine;
use softnc_core::Axes;
use softnc_machine::MachineProfile;

/// Where the checks home the axes (mm): off zero, signs mixed.
pub const HOME_MM: Axes<f64> = Axes([12.5, -7.25, 3.0]);
/// The move [`follows_when_enabled`] and [`ignores_commands_when_disabled`] command
/// on each axis (mm).
pub const MOVE_MM: f64 = 1.0;
/// Counts an encoder at rest may jitter by.
pub const REST_JITTER_COUNTS: i64 = 1;

/// Every check but [`deterministic`], on backends from `make` with `profile`'s
/// controllers where a check closes the loop.
pub fn run<B: ServoBackend>(name: &str, profile: &MachineProfile, make: &dyn Fn() -> B) {
    describes_itself(name, &make());
    homes_and_enables(name, &mut make());
    stands_still_on_a_holding_command(name, &mut make());
    follows_when_enabled(name, profile, make());
    ignores_commands_when_disabled(name, profile, make());
}

/// Axis count within [`MAX_AXES`], a finite positive resolution per axis.
pub fn describes_itself<B: ServoBackend>(name: &str, b: &B) {
    assert!(
        b.axes() >= 1 && b.axes() <= MAX_AXES,
        "{name}: {} axes",
        b.axes()
    );
    for i in 0..b.axes() {
        let res = b.mm_per_count(i);
        assert!(
            res > 0.0 && res.is_finite(),
            "{name}: axis {i} resolution {res}"
        );
    }
}

/// `home` makes the counts read the homed position (to a count); `enable` leaves
/// every axis enabled and without fault.
pub fn homes_and_enables<B: ServoBackend>(name: &str, b: &mut B) {
    b.enable().unwrap_or_else(|e| panic!("{name}: enable: {e}"));
    b.home(HOME_MM);
    for (i, &home_mm) in HOME_MM.iter().enumerate().take(b.axes()) {
        let res = b.mm_per_count(i);
        let pos = b.read_counts()[i] as f64 * res;
        assert!(
            (pos - home_mm).abs() <= res * (1 + REST_JITTER_COUNTS) as f64,
            "{name}: axis {i} homed to {pos}, not {home_mm}"
        );
        let st = b.read_status()[i];
        assert!(st.enabled, "{name}: axis {i} not enabled after enable()");
        assert!(!st.fault, "{name}: axis {i} faulted at rest");
    }
}

/// The holding command (position mode: where it is; velocity and effort: zero)
/// keeps every axis where it is, cycle after cycle, without fault.
pub fn stands_still_on_a_holding_command<B: ServoBackend>(name: &str, b: &mut B) {
    b.enable().unwrap_or_else(|e| panic!("{name}: enable: {e}"));
    b.home(HOME_MM);
    let hold = holding_command(b, HOME_MM);
    let before = b.read_counts();
    for k in 0..500 {
        b.write_commands(hold);
        b.cycle()
            .unwrap_or_else(|e| panic!("{name}: cycle {k} at rest: {e}"));
    }
    let after = b.read_counts();
    for i in 0..b.axes() {
        assert!(
            (after[i] - before[i]).abs() <= REST_JITTER_COUNTS,
            "{name}: axis {i} moved {} counts while held",
            after[i] - before[i]
        );
        assert!(b.read_currents()[i].is_finite(), "{name}: axis {i} current");
        assert!(!b.read_status()[i].fault, "{name}: axis {i} faulted");
    }
}

/// Through the profile's controllers (the [`CycleEngine`] the daemon runs), a ramp
/// of [`MOVE_MM`] on every axis is followed: each axis ends within a tenth of the
/// move of its command.
pub fn follows_when_enabled<B: ServoBackend>(name: &str, profile: &MachineProfile, b: B) {
    let (start, end) = ramp_through(name, profile, b, true);
    for i in 0..MAX_AXES {
        let moved = end[i] - start[i];
        assert!(
            (moved - MOVE_MM).abs() < 0.1 * MOVE_MM,
            "{name}: axis {i} moved {moved} mm of a {MOVE_MM} mm command"
        );
    }
}

/// After `disable`, the same ramp does not move any axis (drives off, or holding),
/// and the status says so.
pub fn ignores_commands_when_disabled<B: ServoBackend>(name: &str, profile: &MachineProfile, b: B) {
    let (start, end) = ramp_through(name, profile, b, false);
    for i in 0..MAX_AXES {
        let moved = end[i] - start[i];
        assert!(
            moved.abs() < 0.01 * MOVE_MM,
            "{name}: axis {i} moved {moved} mm while disabled"
        );
    }
}

/// Two backends from `make` given the same commands read the same counts, bit for
/// bit (simulated and loopback backends; not real drives).
pub fn deterministic<B: ServoBackend>(name: &str, profile: &MachineProfile, make: &dyn Fn() -> B) {
    let run = || {
        let mut e = CycleEngine::new(profile, make());
        e.reset(HOME_MM);
        let mut counts = Vec::new();
        for k in 0..600 {
            let x = (k as f64 / 600.0) * MOVE_MM;
            let cmd = HOME_MM.map(|h| h + x);
            e.step(cmd, k % 2 == 0)
                .unwrap_or_else(|err| panic!("{name}: cycle {k}: {err}"));
            counts.push(e.backend().read_counts());
        }
        counts
    };
    assert!(
        run() == run(),
        "{name}: two runs of the same commands differ"
    );
}

fn holding_command<B: ServoBackend>(b: &B, at_mm: Axes<f64>) -> Axes<f64> {
    let mut hold = Axes::splat(0.0);
    for (i, h) in hold.iter_mut().enumerate() {
        *h = match b.command_mode(i) {
            CommandMode::Position => at_mm[i],
            CommandMode::Velocity | CommandMode::Effort => 0.0,
        };
    }
    hold
}

/// Ramp every axis by [`MOVE_MM`] over 0.5 s and hold 1 s, drives enabled or not;
/// the measured positions before and after (mm).
fn ramp_through<B: ServoBackend>(
    name: &str,
    profile: &MachineProfile,
    b: B,
    enabled: bool,
) -> (Axes<f64>, Axes<f64>) {
    let mut e = CycleEngine::try_new(profile, b)
        .unwrap_or_else(|err| panic!("{name}: the profile's controllers: {err}"));
    e.reset(HOME_MM);
    if enabled {
        e.backend_mut()
            .enable()
            .unwrap_or_else(|err| panic!("{name}: enable: {err}"));
    } else {
        e.backend_mut().disable();
        let st = e.backend().read_status();
        assert!(
            st.iter().all(|s| !s.enabled),
            "{name}: enabled after disable(): {st:?}"
        );
    }
    let start = e.measured_mm();
    let cycle_s = profile.interpolation_cycle_s;
    let ramp = (0.5 / cycle_s).round() as usize;
    let hold = (1.0 / cycle_s).round() as usize;
    for k in 0..ramp + hold {
        let x = MOVE_MM * (k.min(ramp) as f64 / ramp as f64);
        let cmd = HOME_MM.map(|h| h + x);
        e.step(cmd, false)
            .unwrap_or_else(|err| panic!("{name}: cycle {k}: {err}"));
    }
    (start, e.measured_mm())
}
