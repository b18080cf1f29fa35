//! Fuzzes the mesh readers (OBJ, PLY ASCII/binary, GLB) and the half-edge construction with arbitrary bytes.
//! Every input must give a mesh or a typed error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nlos_mesh::io;

fuzz_target!(|data: &[u8]| {
    for read in [io::read_obj, io::read_ply, io::read_glb, io::read_any] {
        if let Ok(soup) = read(data, "fuzz") {
            let _ = soup.into_mesh(Default::default());
        }
    }
});
