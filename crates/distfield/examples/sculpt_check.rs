//! Diagnostics (not part of the crate's API): subtract a tool from a
//! unified or offset field, write the extracted surface, and report where it
//! differs most from the exact result, both ways, in units of `H`
//! (every vertex and 16 points per triangle, as `examples/worst.rs`).
//! cargo run --release -p surfrecon-distfield --example sculpt_check -- FIELD.udf|odf TOOL REF H OUT.ply [OUT.udf|odf]
//! TOOL: sphere:x,y,z,r | box:x0,y0,z0,x1,y1,z1 | cylinder:x0,y0,z0,x1,y1,z1,r
use surfrecon_distfield::format::AnyField;
use surfrecon_distfield::query::{deviation, MeshQuery};
use surfrecon_distfield::sculpt::{Operation, Tool};
use surfrecon_geom::{io, DVec3, Geometry};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut field = AnyField::read(std::path::Path::new(&args[0])).unwrap();
    let (kind, rest) = args[1].split_once(':').unwrap();
    let x: Vec<f64> = rest.split(',').map(|s| s.parse().unwrap()).collect();
    let v = |x: &[f64]| DVec3::new(x[0], x[1], x[2]);
    let tool = match kind {
        "sphere" => Tool::Sphere {
            centre: v(&x),
            radius: x[3],
        },
        "box" => Tool::Box {
            min: v(&x[..3]),
            max: v(&x[3..]),
        },
        _ => Tool::Cylinder {
            a: v(&x[..3]),
            b: v(&x[3..6]),
            radius: x[6],
        },
    };
    let reference = io::read(std::path::Path::new(&args[2])).unwrap().to_mesh();
    let h: f64 = args[3].parse().unwrap();
    let start = std::time::Instant::now();
    let report = field.sculpt(Operation::Subtract, &tool).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    if let Some(path) = args.get(5) {
        // The sculpted field too, for `examples/probe_sculpt.rs`.
        field.write(std::path::Path::new(path)).unwrap();
    }
    let out = field.surface();
    io::write(&args[4], &Geometry::from_mesh(out.clone())).unwrap();
    let (to_ref, to_out) = (
        MeshQuery::new(&reference).unwrap(),
        MeshQuery::new(&out).unwrap(),
    );
    let there = deviation(&out, &to_ref, 16);
    let back = deviation(&reference, &to_out, 16);
    println!(
        "{}: sculpt {seconds:.2} s, edge points {} kept {}, repaired {}, thin {}, settled {}, further {}, corner sets {}, out->ref max {:.3} h mean {:.4} h at {:.3}; ref->out max {:.3} h mean {:.4} h at {:.3}",
        args[1],
        report.edge_points,
        report.kept,
        report.repaired,
        report.thin,
        report.settled,
        report.further,
        report.corner_sets,
        there.max / h,
        there.mean / h,
        there.worst,
        back.max / h,
        back.mean / h,
        back.worst
    );
}
