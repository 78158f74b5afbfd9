//! Fuzzy-logic controller settings (paper 001, eq 2–8): linguistic variables, rule
//! base, integral gain and output range, as written in a machine profile
//! (`servo.axes[i].controller.fuzzy`) or in `config/fuzzy/*.ron`, validated with RON
//! paths. The controller that runs them is `softnc_control::fuzzy::FuzzyController`.

use serde::{Deserialize, Serialize};
use softnc_core::ron_file::{parse_ron, ConfigError};

/// Largest number of fuzzy sets a variable may have (arrays are this size).
pub const MAX_SETS: usize = 11;

/// One linguistic variable: the names of its sets and their centres, in increasing order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FuzzyVariable {
    /// Set names, most negative first (e.g. NL NM NS ZR PS PM PL).
    pub names: Vec<String>,
    /// Set centres, strictly increasing; each set's feet sit on its neighbours' centres.
    pub centres: Vec<f64>,
}

/// A fuzzy controller as written in a machine profile or `config/fuzzy/*.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FuzzyConfig {
    /// Length of one input unit (e and Δe are counted in it), mm. Paper: 1 BLU = 0.01 mm.
    pub input_unit_mm: f64,
    /// Error e(k) = command − position, in input units.
    pub e: FuzzyVariable,
    /// Error change Δe(k) = e(k) − e(k−1), in input units per sample.
    pub de: FuzzyVariable,
    /// Controller output u, in output units (DAC counts in the paper).
    pub u: FuzzyVariable,
    /// `rules[i][j]` = name of the output set for e in set i and Δe in set j
    /// (rows follow `e.names`, columns `de.names`).
    pub rules: Vec<Vec<String>>,
    /// Integral gain K_I (eq 3), output units per input unit per sample.
    pub k_i: f64,
    /// Lower output limit (−128 for a signed 8-bit DAC).
    pub u_min: f64,
    /// Upper output limit (127 for a signed 8-bit DAC).
    pub u_max: f64,
}

impl FuzzyConfig {
    /// Parse and validate RON text; `file` names it in errors.
    pub fn from_ron_str(text: &str, file: &str) -> Result<Self, ConfigError> {
        let cfg: FuzzyConfig = parse_ron(text, file)?;
        cfg.validate_at(file, "")?;
        Ok(cfg)
    }

    /// Load and validate a RON file.
    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let (file, text) = softnc_core::ron_file::read_text(path)?;
        Self::from_ron_str(&text, &file)
    }

    /// Check sizes, names and centres. `prefix` is this config's RON path inside an
    /// enclosing document (`""` at the root, `"axes[0].fuzzy"` inside a profile); the
    /// first bad field is reported with its full path.
    #[allow(clippy::too_many_lines)]
    pub fn validate_at(&self, file: &str, prefix: &str) -> Result<(), ConfigError> {
        let path = |p: &str| {
            if prefix.is_empty() {
                p.to_string()
            } else {
                format!("{prefix}.{p}")
            }
        };
        let bad = |p: String, reason: String| ConfigError::Invalid {
            file: file.to_string(),
            path: p,
            reason,
        };
        if !(self.input_unit_mm.is_finite() && self.input_unit_mm > 0.0) {
            return Err(bad(
                path("input_unit_mm"),
                format!("must be a finite number > 0 (got {})", self.input_unit_mm),
            ));
        }
        for (field, var) in [("e", &self.e), ("de", &self.de), ("u", &self.u)] {
            let n = var.names.len();
            if !(2..=MAX_SETS).contains(&n) {
                return Err(bad(
                    path(&format!("{field}.names")),
                    format!("needs 2 to {MAX_SETS} sets (got {n})"),
                ));
            }
            if var.centres.len() != n {
                return Err(bad(
                    path(&format!("{field}.centres")),
                    format!("needs one centre per set: {n} (got {})", var.centres.len()),
                ));
            }
            for (k, name) in var.names.iter().enumerate() {
                if var.names[..k].contains(name) {
                    return Err(bad(
                        path(&format!("{field}.names[{k}]")),
                        format!("set name \"{name}\" appears twice"),
                    ));
                }
            }
            for (k, c) in var.centres.iter().enumerate() {
                if !c.is_finite() {
                    return Err(bad(
                        path(&format!("{field}.centres[{k}]")),
                        format!("must be a finite number (got {c})"),
                    ));
                }
                if k > 0 && *c <= var.centres[k - 1] {
                    return Err(bad(
                        path(&format!("{field}.centres[{k}]")),
                        format!(
                            "centres must increase strictly ({} then {c})",
                            var.centres[k - 1]
                        ),
                    ));
                }
            }
        }
        if self.rules.len() != self.e.names.len() {
            return Err(bad(
                path("rules"),
                format!(
                    "needs one row per e set: {} (got {})",
                    self.e.names.len(),
                    self.rules.len()
                ),
            ));
        }
        for (i, row) in self.rules.iter().enumerate() {
            if row.len() != self.de.names.len() {
                return Err(bad(
                    path(&format!("rules[{i}]")),
                    format!(
                        "needs one entry per de set: {} (got {})",
                        self.de.names.len(),
                        row.len()
                    ),
                ));
            }
            for (j, name) in row.iter().enumerate() {
                if !self.u.names.contains(name) {
                    return Err(bad(
                        path(&format!("rules[{i}][{j}]")),
                        format!(
                            "unknown output set \"{name}\" (u.names: {})",
                            self.u.names.join(" ")
                        ),
                    ));
                }
            }
        }
        if !(self.k_i.is_finite() && self.k_i >= 0.0) {
            return Err(bad(
                path("k_i"),
                format!("must be a finite number >= 0 (got {})", self.k_i),
            ));
        }
        if !(self.u_min.is_finite() && self.u_max.is_finite() && self.u_min < self.u_max) {
            return Err(bad(
                path("u_max"),
                format!(
                    "u_min and u_max must be finite with u_min < u_max (got {} .. {})",
                    self.u_min, self.u_max
                ),
            ));
        }
        Ok(())
    }
}
