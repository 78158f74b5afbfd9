//! The operator contract on the wire: round trips, readers that tolerate what they
//! do not know, job records written before the contract, and replies too large for
//! the payload.

use softnc_api::*;

fn status() -> Status {
    Status {
        api_version: API_VERSION,
        state: MachineState::Running,
        homed: vec![true, true, false],
        checking: None,
        machine_mm: Some([1.0, 2.0, 3.0]),
        work_mm: Some([0.5, 2.0, f64::NAN]),
        distance_to_go_mm: [1.5, 0.0, -0.25],
        coords: "G55".into(),
        offsets: ActiveOffsets {
            g5x_mm: [0.5, 0.0, 0.0],
            rotation_deg: 0.0,
            g92_mm: [0.0; 3],
            tool_offset_mm: [0.0, 0.0, 12.5],
        },
        tool: 3,
        modal: Some(vec!["G55".into(), "M8".into()]),
        coolant: Coolant {
            mist: false,
            flood: true,
        },
        params_error: None,
        modal_error: None,
        unsaved: Unsaved {
            job_history: Some("read-only file system".into()),
            ..Unsaved::default()
        },
        abandoned_checks: 0,
        switches: Switches {
            single_block: true,
            optional_stop: true,
            block_delete: false,
        },
        program_line: Some(12),
        feed_override: 0.8,
        rapid_override: 0.5,
        spindle_override: Some(1.0),
        spindle_rpm: Some(12000.0),
        spindle: Some(softnc_api::Spindle {
            commanded_rpm: 12000.0,
            actual_rpm: 11990.0,
            at_speed: true,
        }),
        tool_prepared: Some(3),
        message: Some("check the coolant".into()),
        prompt: None,
        limits_tripped: vec!["X max".into()],
        limits_overridden: true,
        pending: Some(MachineState::Idle),
        adaptive_force: Some(AdaptiveForce {
            override_fraction: 0.9,
            revolutions: 40,
            force_n: None,
        }),
        job: Some(JobStatus {
            record: record(7, Outcome::Running),
            progress: 0.25,
        }),
        axes: Some(AxesStatus {
            cmd_mm: vec![1.0, 2.0, 3.0],
            actual_mm: vec![1.0, 2.0, 3.0],
            following_err_um: vec![0.1, 0.2, 0.3],
            contour_err_um: Some(0.4),
            ring_fill: 64,
        }),
        processes: Processes {
            interp: ProcessHealth::Alive,
            position: ProcessHealth::Alive,
            supervisor: ProcessHealth::Unseen,
        },
        loops: Loops {
            interp: Some(LoopTiming::default()),
            position: None,
            bus: None,
        },
        alarms: vec![Alarm {
            code: AlarmKind::FollowingError,
            job_id: 7,
            message: "X 2.1 mm".into(),
        }],
    }
}

fn record(job_id: u64, outcome: Outcome) -> JobRecord {
    JobRecord {
        job_id,
        path: format!("/shop/job{job_id}.ngc"),
        submitted_unix_s: 1_764_000_000,
        outcome,
        planned_samples: 1000,
        cycles: 250,
        planned_path_mm: 100.0,
        path_mm: 25.0,
        accuracy: Accuracy {
            contour_max_abs_um: 1.5,
            contour_rms_um: 0.5,
            following_max_abs_um: vec![1.0, 2.0, 3.0],
        },
        notes: vec!["a note".into()],
        alarms: vec![],
        program: Some("/data/programs/ab.ngc".into()),
        sha256: Some("ab".into()),
        mdi: None,
        from_line: None,
        adaptive_force: false,
    }
}

/// Every request, each variant once.
fn every_request() -> Vec<Request> {
    vec![
        Request::SubmitJob {
            path: "/shop/a.ngc".into(),
            from_line: Some(12),
            adaptive_force: true,
        },
        Request::SubmitJob {
            path: "/shop/b.ngc".into(),
            from_line: None,
            adaptive_force: false,
        },
        Request::Hold,
        Request::Resume,
        Request::Step,
        Request::Abort,
        Request::FeedOverride { fraction: 1.25 },
        Request::SpindleOverride { fraction: 0.5 },
        Request::RapidOverride { fraction: 0.25 },
        Request::EStop,
        Request::Reset,
        Request::MachineOn,
        Request::MachineOff,
        Request::OverrideLimits,
        Request::Home { axis: None },
        Request::Home {
            axis: Some(Axis::Z),
        },
        Request::Jog {
            axis: Axis::X,
            speed_mm_per_min: -1200.0,
        },
        Request::JogStep {
            axis: Axis::Y,
            distance_mm: 0.01,
        },
        Request::Mdi {
            blocks: "G0 X10 \"quoted\"\nG1 Y5 F100".into(),
        },
        Request::TouchOff {
            axis: Axis::Z,
            value_mm: 0.0,
            coords: Some("G55".into()),
        },
        Request::ToolSet {
            tool: 4,
            length_mm: 42.5,
            diameter_mm: Some(6.0),
        },
        Request::Offsets,
        Request::Tools,
        Request::SingleBlock { on: true },
        Request::OptionalStop { on: false },
        Request::BlockDelete { on: true },
        Request::Status,
        Request::Jobs { offset: 40 },
        Request::Shutdown,
    ]
}

#[test]
fn every_request_round_trips_through_the_wire() {
    for r in every_request() {
        let text = encode_request(&r, 4096).unwrap();
        assert!(text.contains("\"api_version\":1"), "{text}");
        assert!(
            text.contains(&format!("\"command\":\"{}\"", r.name())),
            "{text}"
        );
        assert_eq!(decode_request(&text).unwrap(), r, "{text}");
    }
}

#[test]
fn every_reply_round_trips_through_the_wire() {
    let replies = vec![
        Reply::accepted(Some(3), "job 3 started: /shop/a.ngc"),
        Reply::accepted(None, "feed override 80 %"),
        Reply::refused("machine is busy (Running); job not started"),
        Reply::Jobs(JobsPage {
            total: 2,
            offset: 0,
            jobs: vec![record(2, Outcome::Completed), record(1, Outcome::Aborted)],
        }),
        Reply::Offsets(OffsetTable {
            active: "G54".into(),
            systems: vec![WorkSystem {
                coords: "G54".into(),
                origin_mm: [1.0, 2.0, 3.0],
                rotation_deg: 0.0,
                active: true,
            }],
            g92_mm: [0.0; 3],
            tool: 0,
            tool_offset_mm: [0.0; 3],
        }),
        Reply::Tools(vec![Tool {
            number: 1,
            length_mm: 10.0,
            diameter_mm: 6.0,
        }]),
    ];
    for r in replies {
        let text = encode_reply(&r, "test", 8192);
        assert_eq!(decode_reply(&text).unwrap(), r, "{text}");
    }
}

#[test]
fn a_status_round_trips_nan_reading_back_as_nan() {
    let s = status();
    let text = encode_reply(&Reply::Status(Box::new(s.clone())), "status", 8192);
    let Reply::Status(back) = decode_reply(&text).unwrap() else {
        panic!("not a status: {text}")
    };
    // NaN is not equal to itself: compare the rest, then the NaN
    assert!(back.work_mm.unwrap()[2].is_nan());
    let mut want = s;
    want.work_mm = None;
    let mut got = *back;
    got.work_mm = None;
    assert_eq!(got, want);
}

#[test]
fn a_status_keeps_the_shape_clients_read() {
    let v = serde_json::to_value(status()).unwrap();
    assert_eq!(v["api_version"], API_VERSION);
    assert_eq!(v["state"], "Running");
    assert_eq!(v["processes"]["interp"], "alive");
    assert_eq!(v["job"]["outcome"], "running");
    assert_eq!(v["job"]["job_id"], 7);
    assert_eq!(v["job"]["progress"], 0.25);
    assert_eq!(v["adaptive_force"]["override"], 0.9);
    assert_eq!(v["alarms"][0]["code"], "FollowingError");
    assert_eq!(v["unsaved"]["job_history"], "read-only file system");
    assert!(v["unsaved"].get("parameters").is_none());
    assert_eq!(v["coolant"]["flood"], true);
    assert_eq!(v["spindle"]["actual_rpm"], 11990.0);
    assert_eq!(v["tool_prepared"], 3);
    assert_eq!(v["message"], "check the coolant");
}

#[test]
fn readers_tolerate_fields_and_variants_they_do_not_know() {
    let mut v = serde_json::to_value(ReplyEnvelope {
        api_version: API_VERSION,
        reply: Reply::Status(Box::new(status())),
    })
    .unwrap();
    v["api_version"] = 99.into();
    v["from_the_future"] = "ignored".into();
    v["reply"]["body"]["spindle_load_pct"] = 40.into();
    v["reply"]["body"]["job"]["operator"] = "ana".into();
    v["reply"]["body"]["job"]["outcome"] = "paused_for_tool_change".into();
    v["reply"]["body"]["state"] = "ToolChange".into();
    v["reply"]["body"]["alarms"][0]["code"] = "Overheat".into();
    v["reply"]["body"]["alarms"][0]["axis"] = "X".into();
    v["reply"]["body"]["processes"]["web"] = "alive".into();
    let Reply::Status(s) = decode_reply(&v.to_string()).unwrap() else {
        panic!("not a status")
    };
    assert_eq!(s.state, MachineState::Unknown);
    assert_eq!(s.job.unwrap().record.outcome, Outcome::Unknown);
    assert_eq!(s.alarms[0].code, AlarmKind::Other);
    // a request with an argument this reader does not know
    let r = decode_request(
        r#"{"api_version": 2, "request": {"command": "jog", "axis": "x", "speed_mm_per_min": 60, "ramp": "soft"}}"#,
    )
    .unwrap();
    assert_eq!(
        r,
        Request::Jog {
            axis: Axis::X,
            speed_mm_per_min: 60.0
        }
    );
    // before versions: no api_version at all
    let r = decode_request(r#"{"request": {"command": "status"}}"#).unwrap();
    assert_eq!(r, Request::Status);
    // not a request of this contract
    assert!(decode_request(r#"{"request": {"command": "fly"}}"#).is_err());
    assert!(decode_request(
        r#"{"request": {"command": "jog", "axis": "Q", "speed_mm_per_min": 1}}"#
    )
    .is_err());
}

#[test]
fn job_records_written_before_the_contract_still_read() {
    // jobs.json as the MMI wrote it before softnc-api: the outcome a plain string,
    // fields added over time missing from older records
    let text = include_str!("fixtures/jobs-before-api.json");
    let jobs: Vec<JobRecord> = serde_json::from_str(text).unwrap();
    let outcomes: Vec<Outcome> = jobs.iter().map(|j| j.outcome).collect();
    assert_eq!(
        outcomes,
        [
            Outcome::Completed,
            Outcome::Aborted,
            Outcome::Interrupted,
            Outcome::Refused
        ]
    );
    assert_eq!(jobs[0].accuracy.following_max_abs_um, [4.5, 3.75, 0.5]);
    assert_eq!(jobs[0].notes, ["learned correction applied (store v3)"]);
    assert_eq!(jobs[0].progress(), 1.0);
    assert_eq!(jobs[1].mdi.as_deref(), Some("G0 X10 Y5"));
    assert_eq!(jobs[1].alarms, ["FollowingError: X 2.1 mm over 2.0 mm"]);
    assert_eq!(jobs[2].from_line, Some(12));
    assert!(jobs[2].adaptive_force);
    assert_eq!(jobs[3].planned_path_mm, 0.0);
    assert!(jobs[3].notes.is_empty());
    // written back, the same records read again (the outcome still a string)
    let again = serde_json::to_string_pretty(&jobs).unwrap();
    assert!(again.contains("\"outcome\": \"interrupted\""));
    let back: Vec<JobRecord> = serde_json::from_str(&again).unwrap();
    assert_eq!(back, jobs);
}

#[test]
fn a_reply_too_large_for_the_payload_is_an_error_reply_never_cut() {
    let page = Reply::Jobs(JobsPage {
        total: 100,
        offset: 0,
        jobs: (0..100).map(|i| record(i, Outcome::Completed)).collect(),
    });
    let whole = encode_reply(&page, "jobs", usize::MAX);
    let capacity = 2048;
    assert!(whole.len() > capacity);
    let text = encode_reply(&page, "jobs", capacity);
    assert!(text.len() <= capacity, "{} bytes", text.len());
    let reply = decode_reply(&text).unwrap();
    assert_eq!(
        reply,
        Reply::TooLarge {
            request: "jobs".into(),
            bytes: whole.len() as u64,
            capacity: capacity as u64,
        }
    );
    assert!(!reply.is_accepted());
    assert!(reply.message().contains("not sent"), "{}", reply.message());
    // one that fits goes as it is
    let small = Reply::accepted(Some(1), "ok");
    assert_eq!(
        decode_reply(&encode_reply(&small, "hold", capacity)).unwrap(),
        small
    );
}

#[test]
fn a_request_too_large_for_the_payload_is_not_sent() {
    let r = Request::Mdi {
        blocks: "G1 X1\n".repeat(1000),
    };
    match encode_request(&r, 1024) {
        Err(e @ ApiError::RequestTooLarge { .. }) => {
            assert!(e.to_string().contains("nothing sent"), "{e}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_process_restarted_alarm_reads_back_and_as_other_for_older_readers() {
    let text = serde_json::to_string(&AlarmKind::ProcessRestarted).unwrap();
    assert_eq!(text, "\"ProcessRestarted\"");
    assert_eq!(
        serde_json::from_str::<AlarmKind>(&text).unwrap(),
        AlarmKind::ProcessRestarted
    );
    // a kind a reader does not know (as ProcessRestarted is to one of before)
    assert_eq!(
        serde_json::from_str::<AlarmKind>("\"ProcessResurrected\"").unwrap(),
        AlarmKind::Other
    );
}

#[test]
fn a_machine_wait_alarm_and_the_machine_fields_of_the_status_read_back() {
    let text = serde_json::to_string(&AlarmKind::MachineWait).unwrap();
    assert_eq!(text, "\"MachineWait\"");
    assert_eq!(
        serde_json::from_str::<AlarmKind>(&text).unwrap(),
        AlarmKind::MachineWait
    );
    // a status written before the spindle, the tool prepared, the message and the
    // prompt reads with none of them; with them, they round-trip
    let mut v = serde_json::to_value(status()).unwrap();
    for k in ["spindle", "tool_prepared", "message", "prompt"] {
        v.as_object_mut().unwrap().remove(k);
    }
    let old: softnc_api::Status = serde_json::from_value(v).unwrap();
    assert_eq!(
        (old.spindle, old.tool_prepared, old.message, old.prompt),
        (None, None, None, None)
    );
    let mut s = status();
    s.prompt = Some("insert T2, then resume".into());
    let back: softnc_api::Status =
        serde_json::from_str(&serde_json::to_string(&s).unwrap()).unwrap();
    assert_eq!(back.prompt.as_deref(), Some("insert T2, then resume"));
    assert_eq!(back.spindle, s.spindle);
    assert_eq!((back.tool_prepared, back.message), (Some(3), s.message));
}
