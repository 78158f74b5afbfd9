//! What the learning store keeps per job (written by `softnc learn`, read by
//! `softnc learn list|show`, `softnc sim --learned` and the daemon's interpolation
//! process), and where the store is.
//!
//! The store folder: an explicit one (`--store DIR`, the daemon's `learning_dir`),
//! else `$SOFTNC_LEARNING_DIR`, else `$XDG_DATA_HOME/softnc/learning`, else
//! `$HOME/.local/share/softnc/learning`, else `./.softnc/learning`.

use crate::markov::{Improvement, MarkovJob, AXES};
use crate::radius_ilc::{Circle, RadiusIlc};
use crate::store::{LearningKey, LearningStore, StoreError};
use softnc_core::ring::CommandSample;
use std::path::{Path, PathBuf};

/// Time the final command is held after the program ends in every learning
/// repetition (s): the learning also sees (and corrects) the final settling, so a
/// Markov entry has the job's planned samples plus this many cycles.
pub const HOLD_S: f64 = 0.2;

/// Feed override the learnt corrections belong to (%): `softnc learn` runs at 100 %.
pub const OVERRIDE_PCT: u32 = 100;

/// The learning law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Law {
    /// Paper 002 eq 5: Markov-parameter learning of the command samples.
    Markov,
    /// Paper 004 eq 8–9: per-degree radius learning of one circle.
    Radius,
}

/// Figures of one learning repetition.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IterationStats {
    /// 0 = the run before any learning.
    pub iteration: usize,
    /// RMS of the error (µm): contour error (Markov) or radius error per degree (radius).
    pub rms_um: f64,
    /// Largest |error| (µm).
    pub max_abs_um: f64,
    /// 2-norm of the learning error e = P_desired − y over all axes and samples (µm);
    /// for the radius law, of the radius error per degree.
    pub norm_um: f64,
    /// Largest and smallest signed error (µm; radius law: outward positive).
    pub max_um: f64,
    /// See `max_um`.
    pub min_um: f64,
}

/// What a law keeps per job.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "law", rename_all = "lowercase")]
// one per store entry, read once per job: the size of the Markov variant costs nothing
#[allow(clippy::large_enum_variant)]
pub enum LawState {
    /// Eq 5: Markov parameters, gains, correction and last error per sample.
    Markov(MarkovJob),
    /// Eq 8–9: the command radius per degree and the last radius error per degree.
    Radius {
        /// Where the circle lies.
        circle: Circle,
        /// Command radii r^k(i).
        ilc: RadiusIlc,
        /// y^{k}(i) − r^d of the last run (mm).
        last_error_mm: Vec<f64>,
    },
}

/// A learning-store entry.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Learned {
    /// Job file as given.
    pub job_file: String,
    /// Machine profile file as given.
    pub profile_file: String,
    /// Seed of the simulated machine.
    pub seed: u64,
    /// Figures of every run so far (the first before any learning).
    pub iterations: Vec<IterationStats>,
    /// The law's state.
    pub state: LawState,
}

impl Learned {
    /// The run whose correction the entry keeps and what it improved: the Markov
    /// law's recorded improvement; for the radius law (which stores only command
    /// radii that improved on the first run, the best so far) the run of smallest RMS
    /// when it is below the first run's.
    pub fn kept(&self) -> Option<Improvement> {
        match &self.state {
            LawState::Markov(mj) => mj.improvement.filter(|i| i.improved()),
            LawState::Radius { .. } => {
                let first = self.iterations.first()?;
                let best = self
                    .iterations
                    .iter()
                    .min_by(|a, b| a.rms_um.total_cmp(&b.rms_um))?;
                Some(Improvement {
                    iteration: best.iteration,
                    unlearned_rms_um: first.rms_um,
                    rms_um: best.rms_um,
                })
                .filter(|i| i.improved())
            }
        }
    }

    /// The law of this entry.
    pub fn law(&self) -> Law {
        match self.state {
            LawState::Markov(_) => Law::Markov,
            LawState::Radius { .. } => Law::Radius,
        }
    }
}

/// The learning store folder: `explicit`, else the documented default.
pub fn store_dir(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    let env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = env("SOFTNC_LEARNING_DIR") {
        return d;
    }
    if let Some(d) = env("XDG_DATA_HOME") {
        return d.join("softnc/learning");
    }
    if let Some(h) = env("HOME") {
        return h.join(".local/share/softnc/learning");
    }
    PathBuf::from(".softnc/learning")
}

/// What the store holds for a job about to run.
#[derive(Debug)]
pub enum Lookup {
    /// No entry for this job, profile and override.
    None,
    /// A Markov entry whose correction fits the job's samples.
    Markov(JobCorrection),
    /// An entry that is not applied, and why (operator's text).
    NotApplied(String),
}

/// The stored Markov correction of a job (eq 5's P_j − P_desired per sample),
/// loaded before motion and indexed per cycle: applying it allocates nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct JobCorrection {
    correction_mm: [Vec<f64>; AXES],
    planned_samples: usize,
    /// Repetitions it was learnt from.
    pub repetitions: usize,
    /// Contour-error RMS of the learning run with this correction on the simulator (µm):
    /// its recorded improvement, below `unlearned_rms_um`.
    pub last_rms_um: Option<f64>,
    /// Contour-error RMS of the same job unlearned (µm), from the same record.
    pub unlearned_rms_um: f64,
    /// The entry's file name in the store.
    pub entry: String,
    fade: Option<Fade>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Fade {
    /// First sample no longer corrected by the stored vector.
    from: usize,
    /// The correction of the sample before it (mm), faded out from there.
    frozen_mm: [f64; AXES],
    /// Samples over which it goes to zero.
    samples: usize,
}

/// The entry of the job `job_bytes` on the profile `profile_bytes` at feed override
/// `override_pct`, checked against the job's planned sample count (`planned_samples`,
/// asked only when there is an entry) at interpolation cycle `cycle_s`: a Markov
/// entry learnt on the same plan has that many samples plus the [`HOLD_S`] tail.
pub fn lookup(
    store: &LearningStore,
    job_bytes: &[u8],
    profile_bytes: &[u8],
    override_pct: u32,
    planned_samples: impl FnOnce() -> usize,
    cycle_s: f64,
) -> Result<Lookup, StoreError> {
    let key = LearningKey::new(job_bytes, profile_bytes, override_pct);
    let Some(e) = store.get::<Learned>(&key)? else {
        return Ok(Lookup::None);
    };
    let entry = key.file_name();
    Ok(match e.state {
        LawState::Radius { .. } => Lookup::NotApplied(format!(
            "learning entry {entry} is paper 004's radius law (one circle, per degree): \
             a different program, not applied to this job's samples"
        )),
        LawState::Markov(mj) => {
            let hold = (HOLD_S / cycle_s).round() as usize;
            let planned_samples = planned_samples();
            if mj.samples() != planned_samples + hold {
                Lookup::NotApplied(format!(
                    "learning entry {entry} has {} samples, this job plans {planned_samples} \
                     (+ {hold} held): planned by another planner version; learn it again",
                    mj.samples()
                ))
            } else if mj.repetitions == 0 {
                Lookup::NotApplied(format!("learning entry {entry} has learnt nothing yet"))
            } else {
                match mj.improvement.filter(|i| i.improved()) {
                    None => Lookup::NotApplied(format!(
                        "learning entry {entry} records no improvement on the unlearned run: \
                         not applied; learn it again"
                    )),
                    Some(imp) => Lookup::Markov(JobCorrection {
                        correction_mm: mj.correction_mm,
                        planned_samples,
                        repetitions: mj.repetitions,
                        last_rms_um: Some(imp.rms_um),
                        unlearned_rms_um: imp.unlearned_rms_um,
                        entry,
                        fade: None,
                    }),
                }
            }
        }
    })
}

impl JobCorrection {
    /// Samples to run after the planned ones: the [`HOLD_S`] tail the correction was
    /// learnt with, holding the final planned position. The correction at the job's
    /// last planned sample is not zero (it leads the decelerating axes, up to the
    /// following error); over the tail it returns to zero (eq 5 has no error ahead of
    /// the last sample), so the job ends on its programmed end point.
    pub fn tail_samples(&self) -> usize {
        self.correction_mm[0]
            .len()
            .saturating_sub(self.planned_samples)
    }

    /// Whether sample `k` is the last one the correction needs: faded out to zero
    /// there, or its last stored sample (where eq 5 leaves it zero: no error ahead).
    pub fn done_at(&self, k: usize) -> bool {
        match self.fade {
            Some(f) => k + 1 >= f.from + f.samples,
            None => k + 1 >= self.correction_mm[0].len(),
        }
    }

    /// The correction to add to the planned command of sample `k` (mm): the stored
    /// one, or after [`JobCorrection::fade_out`] the faded one; zero past the end.
    pub fn at(&self, k: usize) -> [f64; AXES] {
        match self.fade {
            Some(f) if k >= f.from => {
                let left = 1.0 - (k - f.from + 1) as f64 / f.samples as f64;
                f.frozen_mm.map(|c| c * left.max(0.0))
            }
            _ => std::array::from_fn(|a| self.correction_mm[a].get(k).copied().unwrap_or(0.0)),
        }
    }

    /// Stop following the stored correction from sample `from` on (the job is
    /// re-timed: a feed override or hold): the correction of sample `from − 1` is
    /// held and ramped linearly to zero, reached at its `samples`-th sample (at least
    /// one), so the command stays
    /// continuous (a dropped correction would be a position step). Only the first
    /// call counts.
    pub fn fade_out(&mut self, from: usize, samples: usize) {
        if self.fade.is_none() {
            let frozen_mm = if from == 0 {
                [0.0; AXES]
            } else {
                self.at(from - 1)
            };
            self.fade = Some(Fade {
                from,
                frozen_mm,
                samples: samples.max(1),
            });
        }
    }

    /// The job's planned command samples with the correction added, followed by the
    /// learnt hold tail ([`JobCorrection::tail_samples`]): the stream a learned job
    /// runs as planned (`softnc sim --learned`; the daemon makes the same one).
    pub fn corrected<I: Iterator<Item = CommandSample>>(&self, planned: I) -> Corrected<'_, I> {
        Corrected {
            correction: self,
            planned,
            k: 0,
            last: None,
            tail_left: self.tail_samples(),
        }
    }

    /// Whether [`JobCorrection::fade_out`] was called.
    pub fn fading(&self) -> bool {
        self.fade.is_some()
    }

    /// Largest |correction| over the samples and axes (mm).
    pub fn max_abs_mm(&self) -> f64 {
        self.correction_mm
            .iter()
            .flatten()
            .fold(0.0, |m, c| m.max(c.abs()))
    }
}

/// See [`JobCorrection::corrected`].
pub struct Corrected<'a, I> {
    correction: &'a JobCorrection,
    planned: I,
    k: usize,
    last: Option<CommandSample>,
    tail_left: usize,
}

impl<I: Iterator<Item = CommandSample>> Iterator for Corrected<'_, I> {
    type Item = CommandSample;

    fn next(&mut self) -> Option<CommandSample> {
        let mut s = match self.planned.next() {
            Some(s) => {
                self.last = Some(s);
                s
            }
            None if self.tail_left > 0 => {
                self.tail_left -= 1;
                CommandSample {
                    feed_move: false,
                    outputs: Default::default(),
                    ..self.last?
                }
            }
            None => return None,
        };
        for (p, d) in s.pos_mm.iter_mut().zip(self.correction.at(self.k)) {
            *p += d;
        }
        self.k += 1;
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("softnc-entry-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// Removes the test's folder when the test ends, also when it fails.
    struct Cleanup(PathBuf);

    impl Drop for Cleanup {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn entry(samples: usize, repetitions: usize) -> Learned {
        let mut mj = MarkovJob::new(Default::default(), 1, Some(0.5), samples);
        for (k, c) in mj.correction_mm[0].iter_mut().enumerate() {
            *c = k as f64 * 1e-3;
        }
        mj.repetitions = repetitions;
        mj.improvement = Some(Improvement {
            iteration: repetitions,
            unlearned_rms_um: 10.0,
            rms_um: 2.0,
        });
        Learned {
            job_file: "job.ngc".into(),
            profile_file: "m.ron".into(),
            seed: 1,
            iterations: vec![],
            state: LawState::Markov(mj),
        }
    }

    #[test]
    fn lookup_checks_key_law_and_length() {
        let store = LearningStore::new(tmpdir("lookup"));
        let _cleanup = Cleanup(store.dir().to_path_buf());
        let key = LearningKey::new(b"job", b"profile", 100);
        // 10 planned samples at 1 ms + 200 held
        store.put(&key, &entry(210, 3)).unwrap();
        let got = lookup(&store, b"job", b"profile", 100, || 10, 1e-3).unwrap();
        let Lookup::Markov(c) = got else {
            panic!("{got:?}")
        };
        assert_eq!(c.at(4), [4e-3, 0.0, 0.0]);
        assert_eq!(c.tail_samples(), 200);
        assert_eq!(c.at(10_000), [0.0; AXES]);
        assert!(matches!(
            lookup(&store, b"job", b"profile", 120, || 10, 1e-3).unwrap(),
            Lookup::None
        ));
        assert!(matches!(
            lookup(&store, b"job", b"profile", 100, || 11, 1e-3).unwrap(),
            Lookup::NotApplied(_)
        ));
        store.put(&key, &entry(210, 0)).unwrap();
        assert!(matches!(
            lookup(&store, b"job", b"profile", 100, || 10, 1e-3).unwrap(),
            Lookup::NotApplied(_)
        ));
        // learnt, but no recorded improvement (or one that is not): not applied
        for imp in [
            None,
            Some(Improvement {
                iteration: 2,
                unlearned_rms_um: 10.0,
                rms_um: 12.0,
            }),
        ] {
            let mut e = entry(210, 3);
            if let LawState::Markov(mj) = &mut e.state {
                mj.improvement = imp;
            }
            store.put(&key, &e).unwrap();
            let got = lookup(&store, b"job", b"profile", 100, || 10, 1e-3).unwrap();
            assert!(
                matches!(&got, Lookup::NotApplied(m) if m.contains("no improvement")),
                "{got:?}"
            );
        }
        store.clear(None).unwrap();
    }

    #[test]
    fn fade_out_holds_then_ramps_to_zero_without_a_step() {
        let LawState::Markov(mj) = entry(210, 1).state else {
            unreachable!()
        };
        let mut c = JobCorrection {
            correction_mm: mj.correction_mm,
            planned_samples: 10,
            repetitions: 1,
            last_rms_um: None,
            unlearned_rms_um: f64::NAN,
            entry: String::new(),
            fade: None,
        };
        assert!(!c.done_at(208) && c.done_at(209));
        c.fade_out(100, 4);
        c.fade_out(150, 50); // only the first counts
        assert!(!c.done_at(102) && c.done_at(103));
        assert_eq!(c.at(99)[0], 99e-3);
        let faded: Vec<f64> = (100..106).map(|k| c.at(k)[0]).collect();
        let want = [0.75, 0.5, 0.25, 0.0, 0.0, 0.0].map(|f| f * 99e-3);
        for (g, w) in faded.iter().zip(want) {
            assert!((g - w).abs() < 1e-15, "{faded:?}");
        }
    }
}
