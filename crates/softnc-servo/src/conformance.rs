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
//! [`run`] includes the I/O boundary's checks ([`run_io`]): a backend without I/O
//! passes them by having no lines.

use crate::backend::{CommandMode, ServoBackend, MAX_AXES};
use crate::engine::CycleEngine;
use crate::io::{
    IoLines, OutputState, RawOutputs, SpindleCommand, RAW_ANALOG_LINES, RAW_DIGITAL_LINES,
};
use softnc_core::machine_io::{MachineOutputs, SpindleDir};
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
    run_io(name, profile, make);
}

/// The spindle speed the I/O checks command (rpm).
pub const SPINDLE_RPM: f64 = 1000.0;
/// How long a spindle may take to reach [`SPINDLE_RPM`] or stop (s).
pub const SPINDLE_SETTLE_S: f64 = 5.0;
/// The fraction of [`SPINDLE_RPM`] within which the spindle counts as there (and
/// within which it counts as stopped).
pub const SPINDLE_BAND: f64 = 0.02;

/// The I/O boundary's checks: lines within the raw counts, inputs finite and
/// silent on lines the backend lacks, an exchange without the axes, and a spindle
/// (where the backend has one) that reaches its command both ways through the
/// exchange alone and through the axes' cycle, stops when disabled, and counts
/// index pulses as it turns.
pub fn run_io<B: ServoBackend>(name: &str, profile: &MachineProfile, make: &dyn Fn() -> B) {
    describes_its_io(name, &make());
    exchanges_io_without_the_axes(name, &mut make());
    spindle_follows_its_command(name, profile, &mut make(), false);
    spindle_follows_its_command(name, profile, &mut make(), true);
    machine_off_is_safe(name, profile, &mut make());
}

/// Line counts within the raw ones; a fresh backend's inputs finite, and zero on
/// lines it does not have.
pub fn describes_its_io<B: ServoBackend>(name: &str, b: &B) {
    let l = b.io_lines();
    assert!(
        l.digital_in <= RAW_DIGITAL_LINES
            && l.digital_out <= RAW_DIGITAL_LINES
            && l.analog_in <= RAW_ANALOG_LINES
            && l.analog_out <= RAW_ANALOG_LINES,
        "{name}: {l:?} beyond the raw lines"
    );
    inputs_within(name, b, &l);
}

fn inputs_within<B: ServoBackend>(name: &str, b: &B, l: &IoLines) {
    let r = b.read_io();
    let beyond = if l.digital_in >= RAW_DIGITAL_LINES {
        0
    } else {
        r.digital >> l.digital_in
    };
    assert_eq!(
        beyond, 0,
        "{name}: inputs beyond its {} lines",
        l.digital_in
    );
    for (k, v) in r.analog.iter().enumerate() {
        assert!(v.is_finite(), "{name}: analog input {k} is {v}");
        assert!(
            k < l.analog_in || *v == 0.0,
            "{name}: analog input {k} beyond its lines reads {v}"
        );
    }
    let s = r.spindle;
    assert!(
        s.rpm.is_finite() && s.revs.is_finite(),
        "{name}: spindle feedback {s:?}"
    );
    if !l.spindle {
        assert_eq!(s, Default::default(), "{name}: feedback without a spindle");
    }
}

/// Outputs written and exchanged without stepping the axes: the exchange succeeds
/// cycle after cycle, the axes stay, the inputs stay within the lines.
pub fn exchanges_io_without_the_axes<B: ServoBackend>(name: &str, b: &mut B) {
    b.enable().unwrap_or_else(|e| panic!("{name}: enable: {e}"));
    b.home(HOME_MM);
    let l = b.io_lines();
    let before = b.read_counts();
    let mut out = RawOutputs::default();
    for k in 0..200u32 {
        // every line toggled in turn, every analog line a value
        out.digital = if l.digital_out == 0 {
            0
        } else {
            1u128 << (k as usize % l.digital_out)
        };
        for (i, a) in out.analog.iter_mut().enumerate().take(l.analog_out) {
            *a = f64::from(k) * 0.01 - i as f64;
        }
        b.write_io(&out);
        b.exchange_io()
            .unwrap_or_else(|e| panic!("{name}: I/O exchange {k}: {e}"));
        inputs_within(name, b, &l);
    }
    assert_eq!(
        b.read_counts(),
        before,
        "{name}: the axes moved on an I/O exchange"
    );
}

/// A spindle (where the backend has one) commanded to [`SPINDLE_RPM`] clockwise,
/// then counter-clockwise, then disabled reaches each within [`SPINDLE_BAND`] in
/// [`SPINDLE_SETTLE_S`]; its index count never falls and, where it reports a
/// position, grows by a pulse per revolution turned (±1). `through_cycle`: the
/// exchange is the axes' cycle (held), else the I/O's alone.
pub fn spindle_follows_its_command<B: ServoBackend>(
    name: &str,
    profile: &MachineProfile,
    b: &mut B,
    through_cycle: bool,
) {
    if !b.io_lines().spindle {
        return;
    }
    b.enable().unwrap_or_else(|e| panic!("{name}: enable: {e}"));
    b.home(HOME_MM);
    let hold = holding_command(b, HOME_MM);
    let cycles = (SPINDLE_SETTLE_S / profile.interpolation_cycle_s).ceil() as usize;
    let band = SPINDLE_BAND * SPINDLE_RPM;
    let mut index = b.read_io().spindle.index_count;
    for (enable, reverse, want) in [
        (true, false, SPINDLE_RPM),
        (true, true, -SPINDLE_RPM),
        (false, false, 0.0),
    ] {
        let out = RawOutputs {
            spindle: SpindleCommand {
                enable,
                reverse,
                rpm: SPINDLE_RPM,
                ..SpindleCommand::default()
            },
            ..RawOutputs::default()
        };
        let index0 = index;
        let mut travel = 0.0f64;
        let mut last = b.read_io().spindle.revs;
        let mut reached = None;
        for k in 0..cycles {
            b.write_io(&out);
            let r = if through_cycle {
                b.write_commands(hold);
                b.cycle()
            } else {
                b.exchange_io()
            };
            r.unwrap_or_else(|e| panic!("{name}: cycle {k}: {e}"));
            let f = b.read_io().spindle;
            assert!(
                f.index_count >= index,
                "{name}: the index count fell from {index} to {}",
                f.index_count
            );
            index = f.index_count;
            travel += (f.revs - last).abs();
            last = f.revs;
            if (f.rpm - want).abs() <= band {
                reached.get_or_insert(k);
            } else {
                reached = None;
            }
        }
        let f = b.read_io().spindle;
        assert!(
            reached.is_some(),
            "{name}: spindle at {} rpm after {SPINDLE_SETTLE_S} s commanded {want} rpm",
            f.rpm
        );
        // a pulse per revolution turned (a reversal may pass one index twice)
        let pulses = (index - index0) as f64;
        assert!(
            travel == 0.0 || (pulses - travel.floor()).abs() <= 2.0,
            "{name}: {pulses} index pulses over {travel} revolutions"
        );
    }
}

/// Through [`crate::io::MachineIo`] and the profile's map: the program's spindle
/// and outputs go out while the machine is on, the safe state (spindle stopped,
/// every output off) while it is off, on this backend's lines.
pub fn machine_off_is_safe<B: ServoBackend>(name: &str, profile: &MachineProfile, b: &mut B) {
    let mut io = crate::io::MachineIo::new(profile, b.io_lines());
    let program = MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: SPINDLE_RPM,
        coolant_mist: true,
        coolant_flood: true,
        tool_change: true,
        digital: u64::MAX,
        analog: [1.0; softnc_core::machine_io::ANALOG_LINES],
        ..MachineOutputs::default()
    };
    let off = OutputState {
        machine_on: false,
        amp_enable: false,
        spindle_override: 1.0,
    };
    let raw = io.outputs(&program, off);
    let safe = io.outputs(&MachineOutputs::safe(), off);
    assert_eq!(
        raw, safe,
        "{name}: outputs while off differ from the safe state"
    );
    assert_eq!(
        raw.spindle,
        SpindleCommand::default(),
        "{name}: spindle while off"
    );
    b.write_io(&raw);
    b.exchange_io()
        .unwrap_or_else(|e| panic!("{name}: I/O exchange: {e}"));
    let on = io.outputs(&program, OutputState::default());
    if b.io_lines().spindle {
        assert!(
            on.spindle.enable,
            "{name}: the spindle is not enabled while on"
        );
    }
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
