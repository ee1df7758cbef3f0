use robocal_data::Lines;
use robocal_pipeline::{AutoSettings, automatic};
use robocal_twin::{Backlash, BacklashSide, TwinConfig};

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().unwrap()).collect();
    for &preload in &args {
        let mut twin = TwinConfig::load(std::env::var("TWIN").unwrap_or("configs/twin/arm5.toml".into())).unwrap();
        if std::env::var("KEEP").is_err() { twin.backlash = vec![Backlash {
            joint: std::env::var("J").map_or(1, |w| w.parse().unwrap()),
            width: std::env::var("W").map_or(0.03f64, |w| w.parse::<f64>().unwrap()).to_radians(),
            side: BacklashSide::Torque { preload },
        }]; }
        if std::env::var("NOGEAR").is_ok() { twin.gear = None; twin.beyond = None; }
        if let Ok(n) = std::env::var("COUNT") { twin.poses.count = n.parse().unwrap(); }
        let data = twin.generate().unwrap().measurements;
        let rows: Vec<&robocal_data::Measurement> = data.rows.iter().collect();
        let torques: Vec<f64> = rows.iter().map(|r| twin.gravity_torques(&r.sample.joints.iter().map(|q| q.to_radians()).collect::<Vec<_>>(), r.sample.load)[std::env::var("J").map_or(1, |w| w.parse::<usize>().unwrap())]).collect();
        let pos = torques.iter().filter(|t| **t + preload >= 0.0).count();
        let settings = AutoSettings {
            folds: 3,
            harmonics: if std::env::var("H").is_ok() { 2 } else { 0 },
            self_weight: std::env::var("H").is_ok(),
            residuals: Vec::new(),
            ..AutoSettings::default()
        };
        let lines = Lines::default();
        let built = automatic(&settings, &twin.nominal, &rows, None, &lines).unwrap();
        let sel = built.selection.as_ref().unwrap();
        println!("preload {preload}: {pos}/{} rows positive", rows.len());
        for c in &sel.candidates {
            println!("  {} {:?} {}", c.name, c.score, c.status);
        }
        for d in &sel.decisions {
            println!("  D {} {} {:?} {:?}", d.stage, d.kept, d.held_out_without, d.held_out_with);
        }
    }
}
