//! The parameter table, as LinuxCNC 2.9 keeps it (`_setup.parameters`,
//! `sub_context[].named_params`; `interp_namedparams.cc`, `interp_array.cc`):
//!
//! - numbered parameters `#1` … `#5601` (`RS274NGC_MAX_PARAMETERS` = 5602), all 0 at
//!   start; some are read-only (5021–5029, 5400–5413, 5420–5428);
//! - named parameters: `#<_name>` global, `#<name>` local to the call level that
//!   assigned it;
//! - assignments on a line are gathered while it is read and take effect after it
//!   (parameters are "set in parallel").

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

/// Numbered parameters are `1..NUM_PARAMS` (LinuxCNC `RS274NGC_MAX_PARAMETERS`).
pub const NUM_PARAMS: usize = 5602;

/// Subroutine arguments are `#1` … `#30` (LinuxCNC `INTERP_SUB_PARAMS`).
pub const SUB_PARAMS: usize = 30;

/// Numbered parameters a program may not assign (LinuxCNC `readonly_parameters`).
pub fn is_readonly(index: usize) -> bool {
    matches!(index, 5021..=5029 | 5400..=5413 | 5420..=5428)
}

/// Whether LinuxCNC always writes parameter `index` to its parameter file
/// (`_required_parameters`: G28/G30 positions, G92, the coordinate systems).
pub fn is_persistent(index: usize) -> bool {
    matches!(index, 5161..=5169 | 5181..=5189 | 5210..=5220)
        || (5221..=5390).contains(&index) && (index - 5221) % 20 < 10
}

/// A parameter file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ParamFileError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line names a parameter outside 1-5601.
    #[error("{path}:{line}: parameter number out of range: {index}")]
    OutOfRange {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// The number read.
        index: i64,
    },
    /// Numbers must increase from line to line (LinuxCNC: "Parameter file out of
    /// order").
    #[error("{path}:{line}: parameter file out of order (#{index} after #{previous})")]
    OutOfOrder {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// The number read.
        index: usize,
        /// The number before it.
        previous: usize,
    },
    /// A line starts with a number but has no value after it.
    #[error("{path}:{line}: expected 'NUMBER VALUE', found {text:?}")]
    BadLine {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// The line.
        text: String,
    },
}

/// FNV-1a: named parameters are short strings looked up on every read of a
/// line that uses them; the standard library's SipHash (built against hostile
/// keys, which a program is not) costs several times more per lookup.
#[derive(Debug, Clone, Copy)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl std::hash::Hasher for Fnv {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// A map hashed with [`Fnv`].
pub type FnvMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<Fnv>>;

/// A map keyed by names, hashed with [`Fnv`].
pub type NameMap<V> = FnvMap<String, V>;

/// The named parameters of one scope (the globals, or the locals of one call
/// level), by slot (see [`Params::slot`]).
#[derive(Debug, Clone, Default)]
struct Scope {
    /// `values[slot]`: the parameter's value, `None` where it is not set.
    values: Vec<Option<f64>>,
    /// The slots set, in the order first set (emptied in that many steps).
    set: Vec<u32>,
}

impl Scope {
    fn get(&self, slot: u32) -> Option<f64> {
        self.values.get(slot as usize).copied().flatten()
    }

    fn put(&mut self, slot: u32, value: f64) {
        let k = slot as usize;
        if self.values.len() <= k {
            self.grow(k);
        }
        if self.values[k].is_none() {
            self.set.push(slot);
        }
        self.values[k] = Some(value);
    }

    /// Room for slot `k` (once per slot and scope: kept out of the assignment's
    /// way).
    #[cold]
    fn grow(&mut self, k: usize) {
        self.values.resize(k + 1, None);
    }

    /// Unset everything (the storage is kept).
    fn clear(&mut self) {
        for &k in &self.set {
            self.values[k as usize] = None;
        }
        self.set.clear();
    }
}

/// The table.
#[derive(Debug, Clone)]
pub struct Params {
    numbered: Vec<f64>,
    /// Parameters that came from a parameter file (written back with it).
    from_file: BTreeSet<usize>,
    /// Every name ever assigned, by its slot: a name keeps its slot for the whole
    /// program, so a compiled value looks the slot up once ([`Params::slot`]) and
    /// reads the value without hashing the name again ([`Params::slot_value`]).
    slots: NameMap<u32>,
    /// `names[slot]`: the name of a slot.
    names: Vec<Box<str>>,
    /// `global[slot]`: whether the name of a slot is global (a leading `_`,
    /// LinuxCNC `interp_namedparams.cc`), so that reads and assignments by slot
    /// do not test the name's text.
    global: Vec<bool>,
    globals: Scope,
    /// Local named parameters per call level (0: the main program), kept in
    /// place: `locals[depth]` is the current level's, the scopes above it are
    /// empty and reused by the next call (no allocation or move per call).
    locals: Vec<Scope>,
    /// The current call level (an index into `locals`).
    depth: usize,
    /// `#1…#30` as each subroutine call found them, [`SUB_PARAMS`] values per
    /// call level entered with [`Params::enter`] (restored by [`Params::leave`]).
    saved_args: Vec<f64>,
    /// Assignments read on the current line, not yet made.
    pending_numbered: Vec<(usize, f64)>,
    pending_named: Vec<(String, f64)>,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            numbered: vec![0.0; NUM_PARAMS],
            from_file: BTreeSet::new(),
            slots: NameMap::default(),
            names: Vec::new(),
            global: Vec::new(),
            globals: Scope::default(),
            locals: vec![Scope::default()],
            depth: 0,
            saved_args: Vec::new(),
            pending_numbered: Vec::new(),
            pending_named: Vec::new(),
        }
    }
}

impl PartialEq for Params {
    /// The same values (numbered, and named in each scope, whatever their slots).
    fn eq(&self, other: &Params) -> bool {
        self.numbered == other.numbered
            && self.from_file == other.from_file
            && self.pending_numbered == other.pending_numbered
            && self.pending_named == other.pending_named
            && self.saved_args == other.saved_args
            && self.scope_entries(&self.globals) == other.scope_entries(&other.globals)
            && self.depth == other.depth
            && self.locals[..=self.depth]
                .iter()
                .zip(&other.locals[..=other.depth])
                .all(|(a, b)| self.scope_entries(a) == other.scope_entries(b))
    }
}

impl Params {
    /// Numbered parameter `index` (0 outside the table).
    pub fn get(&self, index: usize) -> f64 {
        self.numbered.get(index).copied().unwrap_or(0.0)
    }

    /// Set numbered parameter `index` now (ignored outside the table).
    pub fn set(&mut self, index: usize, value: f64) {
        if let Some(p) = self.numbered.get_mut(index) {
            *p = value;
        }
    }

    /// A named parameter as assigned by the program: globals (leading `_`) or the
    /// locals of the current call level.
    pub fn named(&self, name: &str) -> Option<f64> {
        self.slot_value(self.slot(name)?)
    }

    /// The slot of a name that has been assigned (in any scope) at some time;
    /// `None` for a name never assigned (it is set nowhere).
    pub fn slot(&self, name: &str) -> Option<u32> {
        self.slots.get(name).copied()
    }

    /// [`Params::named`] of the name of slot `slot`: its value in its scope (the
    /// globals for a leading `_`, else the current call level's locals).
    pub fn slot_value(&self, slot: u32) -> Option<f64> {
        if *self.global.get(slot as usize)? {
            self.globals.get(slot)
        } else {
            self.locals[self.depth].get(slot)
        }
    }

    /// Set a named parameter now, in its scope.
    pub fn set_named(&mut self, name: &str, value: f64) {
        let slot = match self.slots.get(name) {
            Some(&k) => k,
            None => {
                let k = self.names.len() as u32;
                self.slots.insert(name.to_string(), k);
                self.names.push(name.into());
                self.global.push(name.starts_with('_'));
                k
            }
        };
        self.set_slot(slot, value);
    }

    /// [`Params::set_named`] of the name of slot `slot` (a slot [`Params::slot`]
    /// gave).
    #[inline]
    pub fn set_slot(&mut self, slot: u32, value: f64) {
        let scope = if self.global[slot as usize] {
            &mut self.globals
        } else {
            &mut self.locals[self.depth]
        };
        scope.put(slot, value);
    }

    /// The named parameters set in `scope`, by name (for comparing tables).
    fn scope_entries(&self, scope: &Scope) -> BTreeMap<&str, f64> {
        scope
            .set
            .iter()
            .filter_map(|&k| Some((&*self.names[k as usize], scope.get(k)?)))
            .collect()
    }

    /// Remember an assignment read on the current line.
    pub fn defer(&mut self, index: usize, value: f64) {
        self.pending_numbered.push((index, value));
    }

    /// Remember a named assignment read on the current line.
    pub fn defer_named(&mut self, name: String, value: f64) {
        self.pending_named.push((name, value));
    }

    /// Make the assignments read on the line, in the order written (numbered first,
    /// then named, as LinuxCNC's `Interp::read` does).
    pub fn commit(&mut self) {
        for k in 0..self.pending_numbered.len() {
            let (i, v) = self.pending_numbered[k];
            self.set(i, v);
        }
        self.pending_numbered.clear();
        let named = std::mem::take(&mut self.pending_named);
        for (n, v) in &named {
            self.set_named(n, *v);
        }
        self.pending_named = named;
        self.pending_named.clear();
    }

    /// Drop the assignments of a line that is not run.
    pub fn discard(&mut self) {
        self.pending_numbered.clear();
        self.pending_named.clear();
    }

    /// Whether the line read assigned anything.
    pub fn has_pending(&self) -> bool {
        !self.pending_numbered.is_empty() || !self.pending_named.is_empty()
    }

    /// Enter a subroutine: a new scope of locals, `#1…#30` saved (on a stack that
    /// [`Params::leave`] pops) and set to `args` (missing ones 0).
    pub fn enter(&mut self, args: &[f64]) {
        self.saved_args
            .extend_from_slice(&self.numbered[1..=SUB_PARAMS]);
        let sub = &mut self.numbered[1..=SUB_PARAMS];
        let given = args.len().min(SUB_PARAMS);
        sub[..given].copy_from_slice(&args[..given]);
        sub[given..].fill(0.0);
        self.push_scope();
    }

    /// Enter an M98 subprogram: a new scope of locals, `#1…#30` passed on as they
    /// are.
    pub fn enter_keep(&mut self) {
        self.push_scope();
    }

    fn push_scope(&mut self) {
        self.depth += 1;
        if self.locals.len() <= self.depth {
            self.locals.push(Scope::default());
        }
    }

    fn pop_scope(&mut self) {
        if self.depth > 0 {
            self.locals[self.depth].clear();
            self.depth -= 1;
        }
    }

    /// Leave an M98 subprogram: its locals dropped.
    pub fn leave_keep(&mut self) {
        self.pop_scope();
    }

    /// Leave a subroutine: its locals dropped, `#1…#30` restored as the matching
    /// [`Params::enter`] saved them.
    pub fn leave(&mut self) {
        if let Some(from) = self.saved_args.len().checked_sub(SUB_PARAMS) {
            self.numbered[1..=SUB_PARAMS].copy_from_slice(&self.saved_args[from..]);
            self.saved_args.truncate(from);
        }
        self.pop_scope();
    }

    /// All numbered parameters (index 0 unused).
    pub fn numbered(&self) -> &[f64] {
        &self.numbered
    }

    /// Parameters from the text of a LinuxCNC parameter file (`NUMBER VALUE` per
    /// line, numbers increasing; other lines are ignored, as `restore_parameters`
    /// does); the others 0. `path` names the file in messages.
    pub fn from_var_text(text: &str, path: &str) -> Result<Params, ParamFileError> {
        let mut p = Params::default();
        let mut previous = 0usize;
        for (k, l) in text.lines().enumerate() {
            let mut it = l.split_whitespace();
            let Some(first) = it.next() else { continue };
            let Ok(index) = first.parse::<i64>() else {
                continue;
            };
            let Some(value) = it
                .next()
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
            else {
                return Err(ParamFileError::BadLine {
                    path: path.into(),
                    line: k + 1,
                    text: l.into(),
                });
            };
            if !(1..NUM_PARAMS as i64).contains(&index) {
                return Err(ParamFileError::OutOfRange {
                    path: path.into(),
                    line: k + 1,
                    index,
                });
            }
            let index = index as usize;
            if index <= previous {
                return Err(ParamFileError::OutOfOrder {
                    path: path.into(),
                    line: k + 1,
                    index,
                    previous,
                });
            }
            previous = index;
            p.numbered[index] = value;
            p.from_file.insert(index);
        }
        Ok(p)
    }

    /// The first parameter LinuxCNC requires in a parameter file
    /// (`_required_parameters`, [`is_persistent`]) that the file read into these
    /// parameters did not hold: `restore_parameters` refuses such a file ("Required
    /// parameter missing"). `None`: all there (or not read from a file).
    pub fn missing_required(&self) -> Option<usize> {
        (1..NUM_PARAMS).find(|&k| is_persistent(k) && !self.from_file.contains(&k))
    }

    /// Read a parameter file; a missing file gives all parameters 0 (as LinuxCNC
    /// starts without one), any other failure is an error.
    pub fn load(path: &Path) -> Result<Params, ParamFileError> {
        match std::fs::read_to_string(path) {
            Ok(text) => Params::from_var_text(&text, &path.display().to_string()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Params::default()),
            Err(source) => Err(ParamFileError::Io {
                path: path.display().to_string(),
                source,
            }),
        }
    }

    /// The parameter file text LinuxCNC's `save_parameters` writes: the persistent
    /// parameters and those read from the file, `%d\t%f` per line.
    pub fn to_var_text(&self) -> String {
        let mut out = String::new();
        for k in 1..NUM_PARAMS {
            if is_persistent(k) || self.from_file.contains(&k) {
                out.push_str(&format!("{k}\t{:.6}\n", self.numbered[k]));
            }
        }
        out
    }

    /// Write the parameter file atomically (a crash leaves the old file or the
    /// new one).
    pub fn save(&self, path: &Path) -> Result<(), ParamFileError> {
        softnc_core::store::write_atomic(path, self.to_var_text().as_bytes()).map_err(|source| {
            ParamFileError::Io {
                path: path.display().to_string(),
                source,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assignments_wait_for_the_end_of_the_line() {
        let mut p = Params::default();
        p.defer(1, 5.0);
        p.defer_named("x".into(), 2.0);
        assert_eq!(p.get(1), 0.0);
        assert_eq!(p.named("x"), None);
        p.commit();
        assert_eq!(p.get(1), 5.0);
        assert_eq!(p.named("x"), Some(2.0));
    }

    #[test]
    fn locals_are_scoped_and_arguments_restored() {
        let mut p = Params::default();
        p.set(1, 9.0);
        p.set_named("a", 1.0);
        p.set_named("_g", 2.0);
        p.enter(&[4.0, 5.0]);
        assert_eq!((p.get(1), p.get(2), p.get(3)), (4.0, 5.0, 0.0));
        assert_eq!(p.named("a"), None);
        assert_eq!(p.named("_g"), Some(2.0));
        p.set_named("a", 3.0);
        p.leave();
        assert_eq!(p.get(1), 9.0);
        assert_eq!(p.named("a"), Some(1.0));
        assert!(is_readonly(5420) && !is_readonly(5220));
    }

    #[test]
    fn slots_read_as_names_in_every_scope() {
        let mut p = Params::default();
        assert_eq!(p.slot("a"), None);
        p.set_named("a", 1.0);
        p.set_named("_g", 2.0);
        let (a, g) = (p.slot("a").unwrap(), p.slot("_g").unwrap());
        assert_ne!(a, g);
        assert_eq!((p.slot_value(a), p.slot_value(g)), (Some(1.0), Some(2.0)));
        // a call: the local is unset there, the global seen; the slot is kept
        p.enter(&[]);
        assert_eq!((p.slot_value(a), p.slot_value(g)), (None, Some(2.0)));
        p.set_named("b", 7.0);
        p.set_named("a", 3.0);
        assert_eq!(p.slot("a"), Some(a));
        assert_eq!(p.slot_value(a), Some(3.0));
        let b = p.slot("b").unwrap();
        p.leave();
        // back: the caller's value, the callee's locals gone (their slots kept)
        assert_eq!((p.slot_value(a), p.slot_value(b)), (Some(1.0), None));
        assert_eq!((p.named("a"), p.named("b")), (Some(1.0), None));
        // the next call starts with no locals again (its scope reused)
        p.enter(&[]);
        assert_eq!((p.slot_value(a), p.slot_value(b)), (None, None));
        p.leave();
        // tables compare by names and values, whatever the slots
        let mut q = Params::default();
        q.set_named("_g", 2.0);
        q.set_named("a", 1.0);
        assert_eq!(p, q);
        q.set_named("a", 4.0);
        assert_ne!(p, q);
    }

    #[test]
    fn nested_scopes_are_kept_by_depth_and_globals_by_flag() {
        let mut p = Params::default();
        p.enter(&[1.0]);
        p.set_named("a", 1.0);
        p.enter(&[2.0]);
        assert_eq!(p.named("a"), None);
        p.set_named("a", 2.0);
        // a global first assigned two levels down is global
        p.set_named("_g", 5.0);
        p.leave();
        assert_eq!(
            (p.get(1), p.named("a"), p.named("_g")),
            (1.0, Some(1.0), Some(5.0))
        );
        p.leave();
        assert_eq!(
            (p.get(1), p.named("a"), p.named("_g")),
            (0.0, None, Some(5.0))
        );
        // the scopes of the levels left are empty when entered again
        p.enter(&[]);
        p.enter(&[]);
        assert_eq!(p.named("a"), None);
        p.leave();
        p.leave();
        // the scopes above the current level do not take part in comparing
        let mut q = Params::default();
        q.set_named("_g", 5.0);
        assert_eq!(p, q);
        q.enter(&[]);
        assert_ne!(p, q);
    }

    #[test]
    fn parameter_files_round_trip_and_bad_ones_are_errors() {
        let p = Params::from_var_text("5161 1.5\n5221\t-2\n# note\n5400 3\n", "v").unwrap();
        assert_eq!((p.get(5161), p.get(5221), p.get(5400)), (1.5, -2.0, 3.0));
        let text = p.to_var_text();
        assert!(text.starts_with("5161\t1.500000\n5162\t0.000000\n"));
        assert!(text.contains("5221\t-2.000000\n") && text.contains("5400\t3.000000\n"));
        assert!(!text.contains("5231\t"), "5231 is not persistent");
        let q = Params::from_var_text(&text, "v").unwrap();
        assert_eq!(q.numbered(), p.numbered());
        assert!(matches!(
            Params::from_var_text("5221 1\n5161 1\n", "v"),
            Err(ParamFileError::OutOfOrder { line: 2, .. })
        ));
        assert!(matches!(
            Params::from_var_text("7000 1\n", "v"),
            Err(ParamFileError::OutOfRange { index: 7000, .. })
        ));
        assert!(matches!(
            Params::from_var_text("5221 x\n", "v"),
            Err(ParamFileError::BadLine { line: 1, .. })
        ));
        let dir = std::env::temp_dir().join(format!("softnc-var-{}", std::process::id()));
        let f = dir.join("m.var");
        assert_eq!(Params::load(&f).unwrap().get(5221), 0.0);
        p.save(&f).unwrap();
        assert_eq!(Params::load(&f).unwrap().get(5221), -2.0);
        std::fs::remove_dir_all(&dir).ok();
    }
}
