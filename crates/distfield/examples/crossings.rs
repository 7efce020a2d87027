//! Diagnostics: the pairs of triangles of a mesh that cross (exact test,
//! `surfrecon_geom::intersections`), with their corners in grid units of
//! a field's grid when given.
//! cargo run --release -p surfrecon-distfield --example crossings -- MESH [ORIGIN_X,Y,Z H]
use surfrecon_geom::{intersections::self_intersections, io, DVec3};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = io::read(std::path::Path::new(&args[0])).unwrap().to_mesh();
    let (origin, h) = match (args.get(1), args.get(2)) {
        (Some(o), Some(h)) => {
            let o: Vec<f64> = o.split(',').map(|s| s.parse().unwrap()).collect();
            (DVec3::new(o[0], o[1], o[2]), h.parse().unwrap())
        }
        _ => (DVec3::ZERO, 1.0),
    };
    let pairs = self_intersections(&mesh);
    println!("{} crossing pairs", pairs.len());
    for [f, g] in pairs {
        for t in [f, g] {
            let c = mesh.triangles[t as usize].map(|v| (mesh.vertices[v as usize] - origin) / h);
            println!("  {t}: {:.3?}", c.map(|p| p.to_array()));
        }
        println!();
    }
}
