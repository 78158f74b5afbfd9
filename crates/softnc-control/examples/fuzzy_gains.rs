//! Print paper 001's FLC surface on the centre grid and its equivalent gains (eq 13).
//!
//! `cargo run -p softnc-control --example fuzzy_gains [config/fuzzy/paper001.ron]`

use softnc_control::fuzzy::{FuzzyConfig, FuzzyController, SectorGrid};

fn main() {
    let cfg = match std::env::args().nth(1) {
        Some(p) => match FuzzyConfig::load(p.as_ref()) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(2);
            }
        },
        None => FuzzyConfig::from_ron_str(
            include_str!("../../../config/fuzzy/paper001.ron"),
            "paper001.ron",
        )
        .expect("config/fuzzy/paper001.ron"),
    };
    let flc = FuzzyController::new(&cfg);
    print!("{:>8}", "e \\ de");
    for d in &cfg.de.centres {
        print!("{d:>7.1}");
    }
    println!();
    for e in &cfg.e.centres {
        print!("{e:>8.1}");
        for d in &cfg.de.centres {
            print!("{:>7.1}", flc.surface(*e, *d));
        }
        println!();
    }
    for (name, grid) in [
        ("centres", SectorGrid::Centres),
        ("dense 840x840", SectorGrid::Dense(840)),
    ] {
        let g = flc.equivalent_gains(grid);
        println!(
            "{name:>14}: K1 [{:.4}, {:.4}]  K2 [{:.4}, {:.4}]  P = {:.4}  D = {:.4}",
            g.k1_min, g.k1_max, g.k2_min, g.k2_max, g.p, g.d
        );
    }
    println!("       Table 4: P = 2.4  D = 6.7 (I = 0.1, shared with the PID)");
}
