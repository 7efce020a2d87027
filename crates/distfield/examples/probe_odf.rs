//! Diagnostics (not part of the crate's API): what the offset field of a
//! mesh holds around given points: per sample its offset from its node
//! and its value (in h), the features of the cells, and the output.
//! cargo run --release -p surfrecon-distfield --example probe_odf -- MESH CELLS x,y,z ...
use surfrecon_distfield::extract::corner_nodes;
use surfrecon_distfield::features::{cell_of, cells_with_features, Features};
use surfrecon_distfield::offset::{build_odf, OdfOptions};
use surfrecon_distfield::query::MeshQuery;
use surfrecon_geom::{io, DVec3};
use surfrecon_grid::GridSize;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = io::read(std::path::Path::new(&args[0])).unwrap().to_mesh();
    let cells: usize = args[1].parse().unwrap();
    let options = OdfOptions {
        size: GridSize::Resolution(cells),
        iterations: std::env::var("ODF_ITERATIONS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(8),
        ..Default::default()
    };
    let (field, report) = build_odf(&mesh, &options).unwrap();
    println!("{report:?} dims {:?}", field.spec.dims);
    let spec = field.spec;
    let h = spec.spacing;
    let query = MeshQuery::new(&mesh).unwrap();
    let features = Features::detect(&mesh, 30.0);
    let fcells = cells_with_features(&mesh, &features, &spec, |_| true);
    let (out, _) = field.extract();
    let o = DVec3::from_array(spec.position([0, 0, 0]));
    let g = |v: DVec3| (v - o) / h;
    for (k, a) in args[2..].iter().enumerate() {
        let v: Vec<f64> = a.split(',').map(|s| s.parse().unwrap()).collect();
        let p = DVec3::new(v[0], v[1], v[2]);
        let gp = g(p);
        println!("== {p} grid {:.3},{:.3},{:.3}", gp.x, gp.y, gp.z);
        let Some(cell) = cell_of(&spec, p) else {
            continue;
        };
        let idx = spec.unlinear(cell);
        println!("cell {idx:?}");
        // The 3x3x3 cells around.
        for dz in -1i64..=1 {
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let c = [idx[0] as i64 + dx, idx[1] as i64 + dy, idx[2] as i64 + dz];
                    let c = spec.linear(c.map(|x| x as usize));
                    if let Some(f) = fcells.get(&c) {
                        let pieces: Vec<String> = f
                            .pieces
                            .iter()
                            .map(|[a, b]| {
                                let (a, b) = (g(*a), g(*b));
                                format!(
                                    "({:.2},{:.2},{:.2})-({:.2},{:.2},{:.2})",
                                    a.x, a.y, a.z, b.x, b.y, b.z
                                )
                            })
                            .collect();
                        let corners: Vec<String> = f
                            .corners
                            .iter()
                            .chain(&f.bends)
                            .map(|c| {
                                let c = g(*c);
                                format!("({:.2},{:.2},{:.2})", c.x, c.y, c.z)
                            })
                            .collect();
                        println!(
                            "  cell {:?}: pieces {} corners/bends {}",
                            spec.unlinear(c),
                            pieces.join(" "),
                            corners.join(" ")
                        );
                    }
                }
            }
        }
        let own: Vec<usize> = corner_nodes(&spec, cell).to_vec();
        // Samples within 1.5 cells of p.
        for n in 0..field.values.len() {
            let node = DVec3::from_array(spec.position(spec.unlinear(n)));
            if (node - p).abs().max_element() <= 1.5 * h {
                let pos = field.position_of(n);
                let off = (pos - node) / h;
                let exact = query.signed_distance(pos) / h;
                let gi = spec.unlinear(n);
                println!(
                    "  sample {:?} off ({:+.3},{:+.3},{:+.3}) value {:+.5} exact {:+.5}{}",
                    gi,
                    off.x,
                    off.y,
                    off.z,
                    field.values[n] / h,
                    exact,
                    if own.contains(&n) { " *" } else { "" }
                );
            }
        }
        if std::env::var_os("TRIS").is_some() {
            for t in 0..out.triangles.len() {
                let [a, b, c] = out.corners(t);
                let m = (a + b + c) / 3.0;
                if (m - p).abs().max_element() < h {
                    let (a, b, c) = (g(a), g(b), g(c));
                    let d = query.signed_distance(m) / h;
                    println!("  tri ({:.2},{:.2},{:.2}) ({:.2},{:.2},{:.2}) ({:.2},{:.2},{:.2}) centroid err {:+.3}", a.x,a.y,a.z,b.x,b.y,b.z,c.x,c.y,c.z, d);
                }
            }
        }
        if std::env::var_os("CROP").is_some() {
            for (name, m) in [("mesh", &mesh), ("out", &out)] {
                let triangles = (0..m.triangles.len())
                    .filter(|&t| {
                        let [a, b, c] = m.corners(t);
                        ((a + b + c) / 3.0 - p).abs().max_element() < 3.0 * h
                    })
                    .map(|t| m.triangles[t])
                    .collect();
                let crop = surfrecon_geom::TriMesh {
                    vertices: m.vertices.clone(),
                    triangles,
                    normals: None,
                };
                let path = format!("/tmp/df19/probe_odf_{k}_{name}.ply");
                io::write(
                    std::path::Path::new(&path),
                    &surfrecon_geom::Geometry::from_mesh(crop),
                )
                .unwrap();
            }
        }
    }
}
