//! Links the `softnc` binary with GCC's unwinder as a static archive (`libgcc_eh.a`,
//! as `gcc -static-libgcc` links C++ programs) where Rust's standard library asks
//! for the shared `libgcc_s.so.1`.
//!
//! Why: every `softnc` process loaded `libgcc_s.so.1` at its start (open, map,
//! relocate) and ran its constructor `__cpu_indicator_init`, whose `cpuid`
//! instructions take about 14 µs each on the virtual machine of docs/perf-log/planner-figures.md.
//! `softnc plan` of a one-line program, 150 interleaved whole-process runs: 0.11 ms
//! less (docs/perf-log/planner-figures.md, "The serial part of `softnc plan`"). The unwinder is
//! the same code (GCC's `unwind-dw2`), found through `dl_iterate_phdr` as a static
//! program finds it; nothing of the program's own changes.
//!
//! How: rustc passes `-lgcc_s`; a directory holding a copy of `libgcc_eh.a` named
//! `libgcc_s.a` goes first on the linker's search path of this one binary, so that
//! `-lgcc_s` finds the archive. Where the C compiler does not know `libgcc_eh.a`
//! (another C library, a cross build, `crt-static`), nothing is changed.

use std::path::PathBuf;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=CC");
    let var = |k: &str| std::env::var(k).unwrap_or_default();
    let static_crt = var("CARGO_CFG_TARGET_FEATURE")
        .split(',')
        .any(|f| f == "crt-static");
    if var("CARGO_CFG_TARGET_OS") != "linux"
        || var("CARGO_CFG_TARGET_ENV") != "gnu"
        || var("TARGET") != var("HOST")
        || static_crt
    {
        return;
    }
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let Ok(out) = Command::new(cc)
        .arg("-print-file-name=libgcc_eh.a")
        .output()
    else {
        return;
    };
    let archive = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    // (a compiler that does not know the file prints its bare name)
    if !out.status.success() || !archive.is_absolute() || !archive.is_file() {
        return;
    }
    let dir = PathBuf::from(var("OUT_DIR")).join("static-unwinder");
    let copied = std::fs::create_dir_all(&dir)
        .and_then(|()| std::fs::copy(&archive, dir.join("libgcc_s.a")));
    if copied.is_ok() {
        println!("cargo:rustc-link-arg-bin=softnc=-L{}", dir.display());
    }
}
