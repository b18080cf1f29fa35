use super::*;

fn tag(t: u32, n: usize) -> Vec<u8> {
    let mut v = t.to_le_bytes().to_vec();
    v.extend_from_slice(&(n as u32).to_le_bytes());
    v
}

fn padded(mut v: Vec<u8>) -> Vec<u8> {
    v.resize(v.len() + pad8(v.len()), 0);
    v
}

/// An uncompressed little-endian file with one variable.
fn file_with(class: u8, dims: &[i32], name: &str, storage: u32, data: &[u8]) -> Vec<u8> {
    let mut body = tag(MI_UINT32, 8);
    body.extend_from_slice(&u32::from(class).to_le_bytes());
    body.extend_from_slice(&0u32.to_le_bytes());
    body.extend(tag(MI_INT32, 4 * dims.len()));
    body.extend(padded(dims.iter().flat_map(|d| d.to_le_bytes()).collect()));
    body.extend(tag(MI_INT8, name.len()));
    body.extend(padded(name.as_bytes().to_vec()));
    body.extend(tag(storage, data.len()));
    body.extend(padded(data.to_vec()));
    let mut f = vec![b' '; 128];
    f[..6].copy_from_slice(b"MATLAB");
    f[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
    f[126..128].copy_from_slice(b"IM");
    f.extend(tag(MI_MATRIX, body.len()));
    f.extend(body);
    f
}

#[test]
fn uint16_storage_in_double_class_reads_as_values() -> Result<()> {
    let data: Vec<u8> = [1u16, 2, 65535, 7].iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = file_with(6, &[2, 2], "x", MI_UINT16, &data);
    let path = Path::new("t.mat");
    let m = MatFile::parse(&bytes, path)?;
    let a = m.numeric("x", "")?;
    assert_eq!(a.header.class, Class::Double);
    assert_eq!(a.to_f64(path)?, vec![1.0, 2.0, 65535.0, 7.0]);
    Ok(())
}

#[test]
fn value_outside_integer_class_is_rejected() {
    let data: Vec<u8> = [300.0f64].iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = file_with(9, &[1, 1], "x", MI_DOUBLE, &data);
    let path = Path::new("t.mat");
    let r = MatFile::parse(&bytes, path).and_then(|m| m.numeric("x", "")?.to_f64(path));
    assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
}

#[test]
fn small_data_element_scalar() -> Result<()> {
    // A uint8 scalar stored in the 4-byte small data element format.
    let mut bytes = file_with(6, &[1, 1], "w", MI_UINT8, &[]);
    // Replace the trailing empty real-part tag (8 bytes) by a small element: count 1, type miUINT8.
    let n = bytes.len();
    bytes[n - 8..n - 4].copy_from_slice(&((1u32 << 16) | MI_UINT8).to_le_bytes());
    bytes[n - 4] = 42;
    let path = Path::new("t.mat");
    assert_eq!(MatFile::parse(&bytes, path)?.numeric("w", "")?.scalar(path)?, 42.0);
    Ok(())
}

#[test]
fn big_endian_files_are_read() -> Result<()> {
    // Build the same file big-endian by hand.
    let be = |v: u32| v.to_be_bytes();
    let mut body = Vec::new();
    body.extend(be(MI_UINT32));
    body.extend(be(8));
    body.extend(be(7)); // single
    body.extend(be(0));
    body.extend(be(MI_INT32));
    body.extend(be(8));
    body.extend(1i32.to_be_bytes());
    body.extend(2i32.to_be_bytes());
    body.extend(be((1 << 16) | MI_INT8)); // small element name "a"
    body.extend([b'a', 0, 0, 0]);
    body.extend(be(MI_SINGLE));
    body.extend(be(8));
    body.extend(1.5f32.to_be_bytes());
    body.extend((-2.0f32).to_be_bytes());
    let mut f = vec![b' '; 128];
    f[..6].copy_from_slice(b"MATLAB");
    f[124..126].copy_from_slice(&0x0100u16.to_be_bytes());
    f[126..128].copy_from_slice(b"MI");
    f.extend(be(MI_MATRIX));
    f.extend(be(body.len() as u32));
    f.extend(body);
    let path = Path::new("be.mat");
    let m = MatFile::parse(&f, path)?;
    assert_eq!(m.header("a").map(|h| h.dims.clone()), Some(vec![1, 2]));
    assert_eq!(m.numeric("a", "")?.to_f32(path)?, vec![1.5, -2.0]);
    Ok(())
}

#[test]
fn compressed_header_longer_than_the_first_prefix() -> Result<()> {
    use std::io::Write;
    // 400 dimensions of 1 (1600 bytes of header): more than SMALL_PREFIX.
    let dims = vec![1i32; 400];
    let plain = file_with(6, &dims, "many", MI_DOUBLE, &2.5f64.to_le_bytes());
    let element = &plain[128..];
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(element).map_err(|e| TransientError::Io { file: "z".into(), source: e })?;
    let c = z.finish().map_err(|e| TransientError::Io { file: "z".into(), source: e })?;
    let mut bytes = plain[..128].to_vec();
    bytes.extend(tag(MI_COMPRESSED, c.len()));
    bytes.extend(c);
    let path = Path::new("z.mat");
    let m = MatFile::parse(&bytes, path)?;
    assert_eq!(m.header("many").map(|h| h.dims.len()), Some(400));
    assert_eq!(m.numeric("many", "")?.scalar(path)?, 2.5);
    Ok(())
}

#[test]
fn huge_dimensions_do_not_allocate() {
    let bytes = file_with(6, &[1 << 20, 1 << 20], "x", MI_DOUBLE, &[0; 8]);
    let path = Path::new("t.mat");
    let r = MatFile::parse(&bytes, path).and_then(|m| m.numeric("x", "").map(|_| ()));
    assert!(matches!(r, Err(TransientError::Malformed { .. })), "{r:?}");
}

#[test]
fn every_prefix_fails_cleanly() {
    let data: Vec<u8> = [1.0f64, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let bytes = file_with(6, &[1, 2], "x", MI_DOUBLE, &data);
    let path = Path::new("t.mat");
    for n in 0..bytes.len() {
        let r = MatFile::parse(&bytes[..n], path).and_then(|m| m.numeric("x", "").map(|_| ()));
        assert!(r.is_err(), "prefix {n} parsed");
    }
}
