//! What the comparisons with `rs274`'s output share: which of its calls softnc
//! makes too.

/// Whether `rs274`'s call `calls[k]`, a `STOP_SPINDLE_TURNING` while the spindle
/// does not turn (`turning`: as the calls before it leave it), is LinuxCNC's
/// implicit stop that softnc does not make (`Interp::implicit_spindle_stop`): the
/// one before a tool change (`START_CHANGE`, `CHANGE_TOOL` next) or at the program
/// end (`PROGRAM_END` next, after the coolant's, the spindle mode's and M30's
/// `PALLET_SHUTTLE`). An explicit M5 of a stopped spindle is made by both.
pub fn is_implicit_stop_softnc_leaves_out(calls: &[&str], k: usize, turning: bool) -> bool {
    let name = |c: &str| c.trim_start().split('(').next().unwrap_or("").to_string();
    if turning || name(calls[k]) != "STOP_SPINDLE_TURNING" {
        return false;
    }
    let next = calls[k + 1..].iter().map(|c| name(c)).find(|n| {
        !matches!(
            n.as_str(),
            "SET_SPINDLE_MODE" | "MIST_OFF" | "FLOOD_OFF" | "PALLET_SHUTTLE" | "COMMENT" | ""
        )
    });
    matches!(
        next.as_deref(),
        Some("START_CHANGE" | "CHANGE_TOOL" | "PROGRAM_END")
    )
}

/// The spindle's state after `rs274`'s call `call`, from `turning` before it.
pub fn turning_after(call: &str, turning: bool) -> bool {
    let call = call.trim_start();
    if call.starts_with("START_SPINDLE_") {
        true
    } else if call.starts_with("STOP_SPINDLE_TURNING") || call.starts_with("ORIENT_SPINDLE") {
        false
    } else {
        turning
    }
}
