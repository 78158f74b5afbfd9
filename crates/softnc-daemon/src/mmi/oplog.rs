//! The log of operator actions: every command the MMI takes or refuses, and every
//! jog its dead-man stops, as one structured `tracing` event (target
//! [`TARGET`]) with the fields `request` (its wire name), `args` (the request as
//! JSON, as the client sent it), `outcome` (`accepted`, `refused`, `checking` — a
//! job or MDI answered once checked, logged again with its end — or
//! `deadman_stop`) and `reason` (the reply's text). Under systemd the events go to
//! the journal with these fields (`journalctl -u softncd`).
//!
//! Queries (`status`, `jobs`, `offsets`, `tools`) change nothing and are not logged
//! when answered (a TUI asks ten times a second); a jog's renewal (a client holds a
//! jog by repeating it every `JOG_RENEW_PERIOD`) is logged at debug level only.

use softnc_api::{Reply, Request};

/// The target of the operator-action events (filter: `RUST_LOG=softnc::operator=info`).
pub const TARGET: &str = "softnc::operator";

/// A request that only reads.
fn is_query(request: &Request) -> bool {
    matches!(
        request,
        Request::Status | Request::Jobs { .. } | Request::Offsets | Request::Tools
    )
}

/// Log the MMI's answer `reply` to `request` (`None`: answered once its program is
/// checked).
pub fn answered(request: &Request, reply: Option<&Reply>) {
    let accepted = reply.is_none_or(Reply::is_accepted);
    if accepted && is_query(request) {
        return;
    }
    let name = request.name();
    let args = serde_json::to_string(request).unwrap_or_default();
    let (outcome, reason) = match reply {
        None => ("checking", String::new()),
        Some(r) if r.is_accepted() => ("accepted", r.message()),
        Some(r) => ("refused", r.message()),
    };
    let renewal = matches!(request, Request::Jog { .. }) && reason.ends_with("renewed");
    if renewal {
        tracing::debug!(target: TARGET, request = name, args = %args, outcome, reason = %reason, "operator request");
    } else if accepted {
        tracing::info!(target: TARGET, request = name, args = %args, outcome, reason = %reason, "operator request");
    } else {
        tracing::warn!(target: TARGET, request = name, args = %args, outcome, reason = %reason, "operator request");
    }
}

/// Log the end of the check of a job, an MDI command or a touch-off (`request`:
/// its wire name, `path`: the program checked).
pub fn checked(request: &str, path: &str, reply: &Reply) {
    let args = serde_json::json!({ "path": path }).to_string();
    let reason = reply.message();
    if reply.is_accepted() {
        tracing::info!(target: TARGET, request, args = %args, outcome = "accepted", reason = %reason, "operator request checked");
    } else {
        tracing::warn!(target: TARGET, request, args = %args, outcome = "refused", reason = %reason, "operator request checked");
    }
}

/// A request the MMI could not read (`reason`: why).
pub fn unreadable(reason: &str) {
    tracing::warn!(target: TARGET, request = "unreadable", args = "", outcome = "refused", reason = %reason, "operator request");
}

/// The dead-man stopped a continuous jog of `axis` (its name) at `speed_mm_per_min`
/// that its client had not renewed for `deadman_s`.
pub fn deadman_stop(axis: &str, speed_mm_per_min: f64, deadman_s: f64) {
    let args =
        serde_json::json!({ "axis": axis, "speed_mm_per_min": speed_mm_per_min }).to_string();
    tracing::warn!(
        target: TARGET,
        request = "jog",
        args = %args,
        outcome = "deadman_stop",
        reason = %format!("its client did not renew it for {deadman_s} s"),
        "operator jog stopped by the dead-man"
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_api::Axis;
    use std::collections::BTreeMap;
    use std::sync::{Arc, Mutex};
    use tracing::field::{Field, Visit};
    use tracing_subscriber::layer::{Context, SubscriberExt};
    use tracing_subscriber::Layer;

    /// One event: its level and its fields as text.
    type Event = (tracing::Level, BTreeMap<String, String>);

    /// Keeps every event of [`TARGET`].
    #[derive(Clone, Default)]
    struct Capture(Arc<Mutex<Vec<Event>>>);

    struct Fields<'a>(&'a mut BTreeMap<String, String>);

    impl Visit for Fields<'_> {
        fn record_str(&mut self, field: &Field, value: &str) {
            self.0.insert(field.name().into(), value.into());
        }
        fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
            self.0.insert(field.name().into(), format!("{value:?}"));
        }
    }

    impl<S: tracing::Subscriber> Layer<S> for Capture {
        fn on_event(&self, event: &tracing::Event<'_>, _: Context<'_, S>) {
            if event.metadata().target() != TARGET {
                return;
            }
            let mut fields = BTreeMap::new();
            event.record(&mut Fields(&mut fields));
            self.0
                .lock()
                .unwrap()
                .push((*event.metadata().level(), fields));
        }
    }

    fn captured(f: impl FnOnce()) -> Vec<Event> {
        let capture = Capture::default();
        let subscriber = tracing_subscriber::registry()
            .with(capture.clone())
            .with(tracing_subscriber::filter::LevelFilter::TRACE);
        tracing::subscriber::with_default(subscriber, f);
        let events = capture.0.lock().unwrap().clone();
        events
    }

    fn field<'a>(e: &'a Event, name: &str) -> &'a str {
        e.1.get(name).map_or("", String::as_str)
    }

    #[test]
    fn actions_and_refusals_are_events_with_their_fields_queries_are_not() {
        let jog = Request::Jog {
            axis: Axis::X,
            speed_mm_per_min: 600.0,
        };
        let events = captured(|| {
            answered(
                &Request::MachineOn,
                Some(&Reply::accepted(None, "machine on")),
            );
            answered(
                &jog,
                Some(&Reply::refused("jog refused (Off): the machine is off")),
            );
            answered(&jog, Some(&Reply::accepted(None, "jog of X renewed")));
            answered(&Request::Status, Some(&Reply::accepted(None, "status")));
            answered(&Request::Status, Some(&Reply::refused("status: not now")));
            answered(
                &Request::SubmitJob {
                    path: "/tmp/a.ngc".into(),
                    from_line: None,
                    adaptive_force: false,
                },
                None,
            );
            checked(
                "submit_job",
                "/tmp/a.ngc",
                &Reply::refused("a.ngc:3: bad word"),
            );
            unreadable("expected value at line 1");
            deadman_stop("Z", -3000.0, 0.1);
            answered(
                &Request::OverrideLimits,
                Some(&Reply::accepted(
                    None,
                    "limit switches overridden (X max) until all are released",
                )),
            );
        });
        let got: Vec<(tracing::Level, &str, &str)> = events
            .iter()
            .map(|e| (e.0, field(e, "request"), field(e, "outcome")))
            .collect();
        use tracing::Level as L;
        assert_eq!(
            got,
            vec![
                (L::INFO, "machine_on", "accepted"),
                (L::WARN, "jog", "refused"),
                (L::DEBUG, "jog", "accepted"),
                (L::WARN, "status", "refused"),
                (L::INFO, "submit_job", "checking"),
                (L::WARN, "submit_job", "refused"),
                (L::WARN, "unreadable", "refused"),
                (L::WARN, "jog", "deadman_stop"),
                (L::INFO, "override_limits", "accepted"),
            ]
        );
        assert_eq!(field(&events[0], "reason"), "machine on");
        assert_eq!(
            field(&events[1], "reason"),
            "jog refused (Off): the machine is off"
        );
        let args: serde_json::Value = serde_json::from_str(field(&events[1], "args")).unwrap();
        assert_eq!(args["axis"], "X");
        assert_eq!(args["speed_mm_per_min"], 600.0);
        assert!(field(&events[4], "args").contains("/tmp/a.ngc"));
        assert_eq!(field(&events[5], "reason"), "a.ngc:3: bad word");
        assert!(field(&events[7], "args").contains("\"Z\""));
        assert!(field(&events[7], "reason").contains("0.1 s"));
    }
}
