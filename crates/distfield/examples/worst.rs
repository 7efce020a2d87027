//! Diagnostics (not part of the crate's API): where two meshes differ
//! most, both ways (exact point-to-triangle distances, 16 points per
//! triangle and every vertex), in units of `H`.
//! cargo run --release -p surfrecon-distfield --example worst -- OUT REF H [PLACES]
use surfrecon_distfield::query::{deviation, lattice_points, MeshQuery};
use surfrecon_geom::{io, DVec3, TriMesh};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let read = |p: &str| io::read(std::path::Path::new(p)).unwrap().to_mesh();
    let (out, reference) = (read(&args[0]), read(&args[1]));
    let h: f64 = args[2].parse().unwrap();
    let places: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(8);
    let (to_ref, to_out) = (
        MeshQuery::new(&reference).unwrap(),
        MeshQuery::new(&out).unwrap(),
    );
    let there = deviation(&out, &to_ref, 16);
    let back = deviation(&reference, &to_out, 16);
    println!(
        "output->reference max {:.3} h mean {:.4} h; reference->output max {:.3} h mean {:.4} h",
        there.max / h,
        there.mean / h,
        back.max / h,
        back.mean / h
    );
    let mut all = far_points(&out, &to_ref, h, "out->ref");
    all.extend(far_points(&reference, &to_out, h, "ref->out"));
    all.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<(f64, DVec3, &str)> = Vec::new();
    for (d, p, way) in all {
        if kept.len() >= places {
            break;
        }
        if kept.iter().all(|k| k.1.distance(p) > 1.5 * h) {
            kept.push((d, p, way));
        }
    }
    for (d, p, way) in kept {
        println!("  {d:.3} h at {:.3},{:.3},{:.3} ({way})", p.x, p.y, p.z);
    }
}

/// Points of `from` (vertices, 16 per triangle) farther than 0.05 h from `to`.
fn far_points<'a>(
    from: &TriMesh,
    to: &MeshQuery,
    h: f64,
    way: &'a str,
) -> Vec<(f64, DVec3, &'a str)> {
    let mut points: Vec<DVec3> = from.vertices.clone();
    for t in 0..from.triangles.len() {
        points.extend(lattice_points(from.corners(t), 4));
    }
    points
        .into_iter()
        .filter_map(|p| {
            let d = to.signed_distance(p).abs() / h;
            (d > 0.05).then_some((d, p, way))
        })
        .collect()
}
