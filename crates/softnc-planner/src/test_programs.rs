//! G-code programs the crate's unit tests share (`#[cfg(test)]` only).

/// A CAM-like program of `joins` line–arc–line steps along X (0.4 mm arcs, both
/// senses, G64 P0.02): line–arc and arc–line joins with, among them, a dwell, a
/// pause (`pause`, `M0` or `M1`), an exact stop, a G64 Q chain before an arc and a
/// tolerance change; with `zero_length` also a zero-length line (the pattern then
/// repeats every nine steps, else every eight). With `wrap_x_mm` the steps go back to
/// X0 by a rapid once past it.
pub(crate) fn fillet_joins_program(
    joins: usize,
    pause: &str,
    zero_length: bool,
    wrap_x_mm: Option<f64>,
) -> String {
    let period = if zero_length { 9 } else { 8 };
    let mut text = String::from("G21 G90 G17 G64 P0.02\nG0 X0 Y0 Z0\nG1 F1200\n");
    let mut x = 0.0;
    for i in 0..joins {
        let pause_line = format!("{pause}\n");
        let extra = match i % period {
            1 => "G4 P0.01\n",
            3 => pause_line.as_str(),
            5 => "G61\nG1 Y0.1\nG1 Y0\nG64 P0.01\n",
            6 => "G1 Y0\nG64 P0.02 Q0.005\nG1 Y0.001\nG1 Y0\nG64 P0.02\n",
            7 if zero_length => "G1 Y0\n",
            _ => "",
        };
        let turn = if i % 2 == 0 { "G2" } else { "G3" };
        text.push_str(&format!(
            "G1 X{:.4} Y0.3\n{turn} X{:.4} Y0.3 R0.4\nG1 X{:.4} Y0\n{extra}",
            x + 1.0,
            x + 1.6,
            x + 2.0
        ));
        x += 2.0;
        if wrap_x_mm.is_some_and(|w| x > w) {
            x = 0.0;
            text.push_str("G0 X0 Y0\n");
        }
    }
    text.push_str("M2\n");
    text
}
