use std::time::Instant;
use surfrecon_geom::io;
use surfrecon_geom::shapes::sample_surface;
use surfrecon_geom::spatial::KdTree;
use surfrecon_svm::*;

fn main() {
    let mesh = io::read("/work/shared/data/stanford_bunny/reconstruction/bun_zipper.ply")
        .unwrap()
        .to_mesh();
    let pc = sample_surface(&mesh, 50000, 11);
    let (model, _) = fit(
        &pc.positions,
        pc.normals.as_ref().unwrap(),
        &FitOptions::default(),
    )
    .unwrap();
    let q = sample_surface(&mesh, 20000, 5).positions;
    let t = Instant::now();
    let v: f64 = q.iter().map(|p| model.value(*p)).sum();
    println!(
        "value: {:.2} us/eval ({v})",
        t.elapsed().as_secs_f64() / q.len() as f64 * 1e6
    );
    for (i, l) in model.levels.iter().enumerate() {
        let tree = KdTree::new(&l.centres);
        let t = Instant::now();
        let mut cnt = 0;
        for p in &q {
            cnt += tree.within(*p, l.width).len();
        }
        println!(
            "level {i}: {} centres, {:.2} us/query, {:.1} results",
            l.centres.len(),
            t.elapsed().as_secs_f64() / q.len() as f64 * 1e6,
            cnt as f64 / q.len() as f64
        );
    }
}
