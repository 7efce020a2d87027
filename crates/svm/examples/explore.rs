use surfrecon_geom::shapes::*;
use surfrecon_geom::DVec3;
use surfrecon_svm::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(5000);
    let c: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(1.0);
    let shape = args.get(3).cloned().unwrap_or("sphere".into());
    let mesh = match shape.as_str() {
        "torus" => torus(1.0, 0.35, 128, 64),
        "box" => cuboid(DVec3::new(-1.0, -0.6, -0.4), DVec3::new(1.0, 0.6, 0.4)),
        _ => icosphere(DVec3::ZERO, 1.0, 5),
    };
    let pc = sample_surface(&mesh, n, 1);
    let mut opts = FitOptions::default();
    opts.c = c;
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .map(|v| v.parse().unwrap())
            .unwrap_or(d)
    };
    if std::env::var("SQ").is_ok() {
        opts.loss = Loss::Squared;
    }
    opts.max_sweeps = env("SWEEPS", 200.0) as usize;
    opts.cell_ratio = env("CELL", opts.cell_ratio);
    opts.min_width_spacings = env("MINW", opts.min_width_spacings);
    opts.offset_ratio = env("OFF", opts.offset_ratio);
    opts.epsilon = env("EPS", opts.epsilon);
    opts.accuracy = env("ACC", opts.accuracy);
    let t = std::time::Instant::now();
    let (model, report) = fit(&pc.positions, pc.normals.as_ref().unwrap(), &opts).unwrap();
    println!(
        "fit {:.3}s diam {:.3} spacing {:.4}",
        t.elapsed().as_secs_f64(),
        report.diameter,
        report.spacing
    );
    for l in &report.levels {
        println!("  {:?}", l);
    }
    let sd = |p: DVec3| -> f64 {
        match shape.as_str() {
            "torus" => {
                let q = DVec3::new(p.x, p.y, 0.0);
                let ring = if q.length() > 0.0 {
                    q.normalize()
                } else {
                    DVec3::X
                };
                (p - ring).length() - 0.35
            }
            "box" => {
                let h = DVec3::new(1.0, 0.6, 0.4);
                let q = p.abs() - h;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
            _ => p.length() - 1.0,
        }
    };
    let mut tr: Vec<(f64, DVec3)> = pc
        .positions
        .iter()
        .map(|p| (model.value(*p).abs(), *p))
        .collect();
    tr.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!("worst training points: {:?}", &tr[..5]);
    for l in 0..model.levels.len() {
        let m = model.without_finest(model.levels.len() - 1 - l);
        println!("  with {} levels f(worst)={:.4}", l + 1, m.value(tr[0].1));
    }
    let test = sample_surface(&mesh, 4000, 99);
    for off in [0.0, 0.01, -0.01, 0.03, -0.03, 0.1, -0.1, 0.3] {
        let mut worst: f64 = 0.0;
        let mut mean = 0.0;
        for (p, nn) in test.positions.iter().zip(test.normals.as_ref().unwrap()) {
            let x = *p + *nn * off;
            let e = (model.value(x) - sd(x)).abs();
            if e > worst && off == 0.0 {
                println!("   worst at {x:.3} f={:.4} sd={:.4}", model.value(x), sd(x));
            }
            worst = worst.max(e);
            mean += e;
        }
        println!(
            "offset {off:+.2}: max err {:.5} ({:.3}% diam) mean {:.5}",
            worst,
            worst / report.diameter * 100.0,
            mean / 4000.0
        );
    }
}
