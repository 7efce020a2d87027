//! A header that declares a huge count in a tiny file must be refused
//! without reserving memory for it: every single allocation while reading
//! stays below a bound, measured by a counting global allocator (this test
//! binary only). Covers the field and shell readers of this crate and the
//! geometry readers of surfrecon-geom it builds on.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use surfrecon_geom::io::{read_bytes, Format};
use surfrecon_grid::field_io::read_field;
use surfrecon_grid::shell::read_shell;

struct Largest;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; it only
// records the largest requested size.
unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Largest = Largest;

/// Bound on any single allocation while refusing a file of under 300 bytes.
const BOUND: usize = 64 * 1024;

/// The largest single allocation while `read` refuses the file `bytes`
/// stored as `name`, and the error message.
fn largest_allocation<E: std::fmt::Display, T>(
    name: &str,
    bytes: &[u8],
    read: impl Fn(&std::path::Path) -> Result<T, E>,
) -> (usize, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    // One measurement at a time: the tests of this file run in parallel.
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    LARGEST.store(0, Ordering::Relaxed);
    let message = match read(&path) {
        Ok(_) => panic!("{name} was accepted"),
        Err(e) => e.to_string(),
    };
    (LARGEST.load(Ordering::Relaxed), message)
}

#[test]
fn billion_value_headers_in_tiny_files_allocate_little() {
    // (Before the fix, the ascii data reader reserved min(count, 2^28)
    // values: 2 GiB for these files.)
    let vtk = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n\
               DIMENSIONS 1000 1000 1000\nPOINT_DATA 1000000000\nSCALARS v double 1\n\
               LOOKUP_TABLE default\n1 2 3\n";
    let nrrd = "NRRD0004\ntype: double\ndimension: 3\nsizes: 1000 1000 1000\n\
                encoding: ascii\n\n1 2\n";
    let raw = "NRRD0004\ntype: double\ndimension: 3\nsizes: 1000 1000 1000\n\
               endian: little\nencoding: raw\n\n12345678";
    for (name, text) in [("big.vtk", vtk), ("big.nrrd", nrrd), ("raw.nrrd", raw)] {
        let (largest, message) = largest_allocation(name, text.as_bytes(), |p| read_field(p));
        assert!(message.contains("1000000000"), "{name}: {message}");
        assert!(largest < BOUND, "{name}: one allocation of {largest} bytes");
    }
}

#[test]
fn billion_element_geometry_headers_allocate_little() {
    let ply_ascii = "ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\n\
                     property float y\nproperty float z\nend_header\n0 0 0\n";
    let ply_binary = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
                      property float y\nproperty float z\nelement face 1000000000\n\
                      property list uchar int vertex_indices\nend_header\n";
    let off = "OFF\n1000000000 1000000000 0\n0 0 0\n";
    let mut stl = vec![0u8; 80];
    stl.extend(1_000_000_000u32.to_le_bytes());
    stl.extend([0u8; 50]);
    let cases: [(&str, &[u8], Format); 4] = [
        ("a.ply", ply_ascii.as_bytes(), Format::Ply),
        ("b.ply", ply_binary.as_bytes(), Format::Ply),
        ("c.off", off.as_bytes(), Format::Off),
        ("d.stl", &stl, Format::Stl),
    ];
    for (name, bytes, format) in cases {
        let read = |p: &std::path::Path| read_bytes(&std::fs::read(p).unwrap(), format, p);
        let (largest, message) = largest_allocation(name, bytes, read);
        assert!(message.contains(name), "{name}: {message}");
        assert!(
            largest < BOUND,
            "{name}: one allocation of {largest} bytes ({message})"
        );
    }
}

#[test]
fn shell_with_a_billion_nodes_declared_allocates_little() {
    let mut shell = b"SRSHELL\0".to_vec();
    shell.extend(1u32.to_le_bytes());
    shell.extend(3u32.to_le_bytes());
    for _ in 0..3 {
        shell.extend(1000u64.to_le_bytes());
    }
    for v in [0.0f64, 0.0, 0.0, 1.0] {
        shell.extend(v.to_le_bytes());
    }
    shell.extend(1_000_000_000u64.to_le_bytes());
    shell.extend([0u8; 20]);
    let (largest, message) = largest_allocation("s.shell", &shell, |p| read_shell(p));
    assert!(message.contains("1000000000 shell nodes"), "{message}");
    assert!(largest < BOUND, "one allocation of {largest} bytes");
}
