//! The workspace's layering holds: every crate of ours depends (normal, dev and build
//! dependencies alike) only on crates of ours in layers below its own, per [`LAYERS`],
//! which is docs/architecture.md's layer table ("Crates (arrows point down only)");
//! the G-code reader and the planner pull in no linear algebra.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// Layer by layer, bottom first: the crates of each.
const LAYERS: &[(&str, &[&str])] = &[
    (
        "bottom",
        &["softnc-core", "softnc-rt", "softnc-test-support"],
    ),
    (
        "libraries",
        &[
            "softnc-gcode",
            "softnc-control",
            "softnc-plant",
            "softnc-adaptive",
            "softnc-learning",
            "softnc-ipc",
            "softnc-api",
        ],
    ),
    ("operator client", &["softnc-client"]),
    (
        "composed",
        &["softnc-planner", "softnc-machine", "softnc-ethercat-emu"],
    ),
    ("servo boundary", &["softnc-servo"]),
    ("backends", &["softnc-sim", "softnc-ethercat"]),
    ("experiments", &["softnc-experiments"]),
    ("processes", &["softnc-daemon"]),
    ("command line", &["softnc-cli", "softnc-web"]),
];

/// Crates of ours that must not depend on nalgebra (directly; their own
/// dependencies are held to the same by the layering).
const NO_LINEAR_ALGEBRA: &[&str] = &["softnc-core", "softnc-gcode", "softnc-planner"];

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn layer_of() -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for (i, (_, crates)) in LAYERS.iter().enumerate() {
        for c in *crates {
            assert!(m.insert(c.to_string(), i).is_none(), "{c} twice in LAYERS");
        }
    }
    m
}

/// Each workspace member and its dependencies: (name, kind: "normal", "dev", "build").
fn members() -> BTreeMap<String, Vec<(String, String)>> {
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| {
                    let kind = d["kind"].as_str().unwrap_or("normal").to_string();
                    (d["name"].as_str().unwrap().to_string(), kind)
                })
                .collect();
            (p["name"].as_str().unwrap().to_string(), deps)
        })
        .collect()
}

#[test]
fn every_crate_depends_only_on_layers_below_it() {
    let layer = layer_of();
    let members = members();
    let listed: Vec<&String> = layer.keys().collect();
    let present: Vec<&String> = members.keys().collect();
    assert_eq!(
        listed, present,
        "LAYERS lists exactly the workspace members"
    );
    let mut wrong = Vec::new();
    for (name, deps) in &members {
        for (d, kind) in deps.iter().filter(|(d, _)| layer.contains_key(d)) {
            if layer[d] >= layer[name] {
                wrong.push(format!(
                    "{name} ({}) depends on {d} ({}) as a {kind} dependency",
                    LAYERS[layer[name]].0, LAYERS[layer[d]].0
                ));
            }
        }
        if NO_LINEAR_ALGEBRA.contains(&name.as_str()) && deps.iter().any(|(d, _)| d == "nalgebra") {
            wrong.push(format!("{name} depends on nalgebra"));
        }
    }
    assert!(wrong.is_empty(), "layering broken:\n{}", wrong.join("\n"));
}

#[test]
fn docs_architecture_layer_table_is_this_one() {
    let text = std::fs::read_to_string(root().join("docs/architecture.md")).unwrap();
    let table = text
        .split("## Crates (arrows point down only)")
        .nth(1)
        .expect("docs/architecture.md has the crates section");
    let mut documented: Vec<(String, Vec<String>)> = Vec::new();
    for row in table.lines().skip_while(|l| !l.starts_with('|')) {
        if !row.starts_with('|') {
            break;
        }
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let (layer, krate) = (cells[1], cells[2].trim_matches('`'));
        if layer == "layer" || layer.starts_with("---") {
            continue;
        }
        if !layer.is_empty() {
            documented.push((layer.to_string(), Vec::new()));
        }
        documented
            .last_mut()
            .expect("the table's first row names its layer")
            .1
            .push(krate.to_string());
    }
    let ours: Vec<(String, Vec<String>)> = LAYERS
        .iter()
        .enumerate()
        .map(|(i, (name, crates))| {
            let mut c: Vec<String> = crates.iter().map(|c| c.to_string()).collect();
            c.sort();
            (format!("{i} {name}"), c)
        })
        .collect();
    for d in &mut documented {
        d.1.sort();
    }
    assert_eq!(documented, ours);
}
