//! Shared checks of the fuzz targets: parsing arbitrary bytes never panics,
//! and whatever parses can be written and read back unchanged (or the
//! writer refuses it with an error, which is reported as a finding: what a
//! reader accepts, its writer must write).

pub mod algo;
pub mod scene;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use surfrecon_geom::io::{read_bytes, to_bytes, Encoding, Format, WriteOptions};

/// Parse `data` as `format`; on success, write the geometry in every
/// encoding of that format and require the same geometry back.
pub fn check(data: &[u8], format: Format) {
    let Ok(geometry) = read_bytes(data, format, "fuzz-input") else {
        return;
    };
    if format == Format::Stl && geometry.triangles.is_empty() {
        return; // an empty solid parses, but STL output needs triangles
    }
    let encodings: &[Encoding] = match format {
        Format::Ply => &[
            Encoding::Ascii,
            Encoding::BinaryLittleEndian,
            Encoding::BinaryBigEndian,
        ],
        // Binary STL rounds to 32-bit floats; the ascii form is exact.
        // Text-only formats ignore the encoding.
        _ => &[Encoding::Ascii],
    };
    for &encoding in encodings {
        let bytes = to_bytes(&geometry, format, WriteOptions { encoding })
            .unwrap_or_else(|e| panic!("parsed geometry not writable as {format}: {e}"));
        if bytes.is_empty() {
            continue; // e.g. an OBJ/XYZ of nothing: reading "" is an error by design
        }
        let again = read_bytes(&bytes, format, "fuzz-rewrite")
            .unwrap_or_else(|e| panic!("written {format} not readable: {e}"));
        assert_eq!(
            again, geometry,
            "{format} {encoding:?} round trip changed the geometry"
        );
    }
}

/// A scratch file of this process (in /dev/shm when it exists, so the
/// path-based readers cost no disk I/O).
pub fn scratch(name: &str) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let base = Path::new("/dev/shm");
        let base = if base.is_dir() {
            base.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("surfrecon-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch directory");
        dir
    });
    dir.join(name)
}

/// `data` stored in the scratch file `name`, for the path-based readers.
pub fn input_file(data: &[u8], name: &str) -> PathBuf {
    let path = scratch(name);
    std::fs::write(&path, data).expect("scratch write");
    path
}

/// NRRD or VTK field (`ext` = "nrrd" / "vtk"): read; when it reads, write
/// it in both field formats and require the same field back.
pub fn check_field(data: &[u8], ext: &str) {
    use surfrecon_grid::field_io::{read_field, write_field, AnyField};
    let Ok(field) = read_field(input_file(data, &format!("in.{ext}"))) else {
        return;
    };
    for out in ["nrrd", "vtk"] {
        let path = scratch(&format!("out.{out}"));
        match &field {
            AnyField::D2(f) => write_field(&path, f),
            AnyField::D3(f) => write_field(&path, f),
        }
        .unwrap_or_else(|e| panic!("{ext} field read but not writable as {out}: {e}"));
        let again =
            read_field(&path).unwrap_or_else(|e| panic!("written {out} field not readable: {e}"));
        assert_eq!(again, field, "{ext} -> {out} round trip changed the field");
    }
}

/// Thin shell: read; when it reads, write and require the same shell back.
pub fn check_shell(data: &[u8]) {
    use surfrecon_grid::shell::{read_shell, write_shell, AnyShell};
    let Ok(shell) = read_shell(input_file(data, "in.shell")) else {
        return;
    };
    let path = scratch("out.shell");
    match &shell {
        AnyShell::D2(s) => write_shell(&path, s),
        AnyShell::D3(s) => write_shell(&path, s),
    }
    .unwrap_or_else(|e| panic!("shell read but not writable: {e}"));
    let again = read_shell(&path).unwrap_or_else(|e| panic!("written shell not readable: {e}"));
    assert_eq!(again, shell, "shell round trip changed it");
}

/// `.svm` model: parse; when it parses, write and require the same model
/// (offset, and per level width, centres and coefficients) back.
pub fn check_svm(data: &[u8]) {
    use surfrecon_svm::SvmModel;
    let Ok(model) = SvmModel::from_bytes(data) else {
        return;
    };
    let mut bytes = Vec::new();
    model.write_to(&mut bytes).expect("write to memory");
    let again = SvmModel::from_bytes(&bytes)
        .unwrap_or_else(|(at, e)| panic!("written model not readable: byte {at}: {e}"));
    assert_eq!(again.offset.to_bits(), model.offset.to_bits());
    assert_eq!(again.levels.len(), model.levels.len());
    for (a, b) in again.levels.iter().zip(&model.levels) {
        assert_eq!(a.width.to_bits(), b.width.to_bits());
        assert_eq!(a.centres, b.centres);
        assert_eq!(a.coefficients, b.coefficients);
    }
}

/// `.odf` offset distance field: read; when it reads, write and require
/// the same field back.
pub fn check_odf(data: &[u8]) {
    use surfrecon_distfield::format::{read_odf, write_odf};
    let Ok(field) = read_odf(&input_file(data, "in.odf")) else {
        return;
    };
    let path = scratch("out.odf");
    write_odf(&path, &field).unwrap_or_else(|e| panic!("odf read but not writable: {e}"));
    let again = read_odf(&path).unwrap_or_else(|e| panic!("written odf not readable: {e}"));
    assert_eq!(again, field, "odf round trip changed the field");
}

/// `.udf` unified distance field: read; when it reads, write and require
/// the same field back.
pub fn check_udf(data: &[u8]) {
    use surfrecon_distfield::format::{read_udf, write_udf};
    let Ok(field) = read_udf(&input_file(data, "in.udf")) else {
        return;
    };
    let path = scratch("out.udf");
    write_udf(&path, &field).unwrap_or_else(|e| panic!("udf read but not writable: {e}"));
    let again = read_udf(&path).unwrap_or_else(|e| panic!("written udf not readable: {e}"));
    assert_eq!(again, field, "udf round trip changed the field");
}
