use rand::{Rng, SeedableRng};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::shapes::{icosphere, sample_surface};
use surfrecon_geom::DVec3;
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::*;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let c: f64 = args[1].parse().unwrap();
    let sq = args.get(2).is_some_and(|a| a == "sq");
    let mut pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 4000, 3);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(17);
    let normals = pc.normals.as_mut().unwrap();
    for _ in 0..200 {
        let p = DVec3::new(rng.random(), rng.random(), rng.random()) * 2.4 - DVec3::splat(1.2);
        let n = DVec3::new(rng.random(), rng.random(), rng.random()) - DVec3::splat(0.5);
        pc.positions.push(p);
        normals.push(n.normalize());
    }
    let mut opts = FitOptions {
        c,
        ..Default::default()
    };
    if sq {
        opts.loss = Loss::Squared;
    }
    let (model, rep) = fit(&pc.positions, pc.normals.as_ref().unwrap(), &opts).unwrap();
    for l in &rep.levels {
        println!("  {:?}", l);
    }
    let outl = &pc.positions[4000..];
    for k in 1..=model.levels.len() {
        let m = model.without_finest(model.levels.len() - k);
        let neg = outl
            .iter()
            .filter(|p| {
                (m.value(**p) < 0.0) != (p.length() < 1.0) && (p.length() - 1.0).abs() > 0.05
            })
            .count();
        let far = outl
            .iter()
            .filter(|p| (p.length() - 1.0).abs() > 0.05)
            .count();
        println!("  levels {k}: {neg}/{far} far outliers with wrong sign");
    }
    for p in outl {
        let v = model.value(*p);
        if (v < 0.0) != (p.length() < 1.0) && (p.length() - 1.0).abs() > 0.05 {
            println!(
                "   wrong: sd {:.3} f {:.3} f1 {:.3} f3 {:.3}",
                p.length() - 1.0,
                v,
                model.without_finest(5).value(*p),
                model.without_finest(3).value(*p)
            );
        }
    }
    let (mesh, _) = mesh_model(
        &model,
        &pc.positions,
        pc.bounds(),
        &MeshOptions {
            resolution: 64,
            ..Default::default()
        },
    )
    .unwrap();
    let t = topology(&mesh);
    let clean = sample_surface(&icosphere(DVec3::ZERO, 1.0, 5), 2000, 99);
    let err = clean
        .positions
        .iter()
        .map(|p| model.value(*p).abs())
        .fold(0.0, f64::max);
    let mean = clean
        .positions
        .iter()
        .map(|p| model.value(*p).abs())
        .sum::<f64>()
        / 2000.0;
    println!("c={c} sq={sq}: components {} watertight {} centres {} levels {}; surface err max {:.4} mean {:.5} (diam {:.3})", t.components, t.watertight, model.centre_count(), rep.levels.len(), err, mean, rep.diameter);
}
