//! A small MATLAB level-5 MAT-file writer for tests: numeric variables in any storage type (independent
//! of the class, as MATLAB does when it stores doubles as uint16), char and cell variables, uncompressed
//! or zlib-compressed (`miCOMPRESSED`, as MATLAB v7 writes), little- or big-endian.
//!
//! Reference: MathWorks, *MAT-File Format*, "Level 5 MAT-File Format".

use std::io::Write;

/// `miINT8` … data types.
pub const MI_INT8: u32 = 1;
pub const MI_UINT8: u32 = 2;
pub const MI_INT16: u32 = 3;
pub const MI_UINT16: u32 = 4;
pub const MI_INT32: u32 = 5;
pub const MI_UINT32: u32 = 6;
pub const MI_SINGLE: u32 = 7;
pub const MI_DOUBLE: u32 = 9;
pub const MI_MATRIX: u32 = 14;
pub const MI_COMPRESSED: u32 = 15;

/// `mxCLASS` codes.
pub const CELL: u8 = 1;
pub const CHAR: u8 = 4;
pub const DOUBLE: u8 = 6;
pub const SINGLE: u8 = 7;
pub const UINT8: u8 = 9;
pub const INT16: u8 = 10;
pub const UINT16: u8 = 11;
pub const INT32: u8 = 12;

/// Stored values with their storage type.
#[derive(Debug, Clone)]
pub enum Stored {
    F64(Vec<f64>),
    F32(Vec<f32>),
    U16(Vec<u16>),
    I16(Vec<i16>),
    U8(Vec<u8>),
    I32(Vec<i32>),
}

impl Stored {
    fn mi_type(&self) -> u32 {
        match self {
            Stored::F64(_) => MI_DOUBLE,
            Stored::F32(_) => MI_SINGLE,
            Stored::U16(_) => MI_UINT16,
            Stored::I16(_) => MI_INT16,
            Stored::U8(_) => MI_UINT8,
            Stored::I32(_) => MI_INT32,
        }
    }

    fn bytes(&self, be: bool) -> Vec<u8> {
        macro_rules! enc {
            ($v:expr) => {
                $v.iter().flat_map(|x| if be { x.to_be_bytes().to_vec() } else { x.to_le_bytes().to_vec() }).collect()
            };
        }
        match self {
            Stored::F64(v) => enc!(v),
            Stored::F32(v) => enc!(v),
            Stored::U16(v) => enc!(v),
            Stored::I16(v) => enc!(v),
            Stored::U8(v) => v.clone(),
            Stored::I32(v) => enc!(v),
        }
    }
}

/// What a variable holds.
#[derive(Debug, Clone)]
pub enum Body {
    /// A numeric array: class code, stored values, complex (then the imaginary part repeats the real).
    Numeric { class: u8, data: Stored, complex: bool },
    /// A char array (stored as miUINT16).
    Char(String),
    /// A 1×1 cell holding an empty double.
    Cell,
}

/// A variable.
#[derive(Debug, Clone)]
pub struct Var {
    pub name: String,
    pub dims: Vec<i32>,
    pub body: Body,
}

/// A double-class variable stored as f64.
pub fn double(name: &str, dims: &[i32], v: Vec<f64>) -> Var {
    Var {
        name: name.into(),
        dims: dims.to_vec(),
        body: Body::Numeric { class: DOUBLE, data: Stored::F64(v), complex: false },
    }
}

/// A variable of class `class` with values stored as `data`.
pub fn stored(name: &str, dims: &[i32], class: u8, data: Stored) -> Var {
    Var { name: name.into(), dims: dims.to_vec(), body: Body::Numeric { class, data, complex: false } }
}

/// A 1×1 double.
pub fn scalar(name: &str, v: f64) -> Var {
    double(name, &[1, 1], vec![v])
}

/// A char variable.
pub fn char_var(name: &str, s: &str) -> Var {
    Var { name: name.into(), dims: vec![1, s.len() as i32], body: Body::Char(s.into()) }
}

/// A 1×1 cell variable.
pub fn cell_var(name: &str) -> Var {
    Var { name: name.into(), dims: vec![1, 1], body: Body::Cell }
}

/// Writer options.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Wrap each variable in a zlib `miCOMPRESSED` element.
    pub compress: bool,
    /// Big-endian file ("MI").
    pub big_endian: bool,
}

struct W {
    be: bool,
}

impl W {
    fn u32(&self, v: u32) -> [u8; 4] {
        if self.be { v.to_be_bytes() } else { v.to_le_bytes() }
    }

    fn tag(&self, out: &mut Vec<u8>, t: u32, n: usize) {
        out.extend(self.u32(t));
        out.extend(self.u32(n as u32));
    }

    /// A sub-element, in small format when it fits in 4 bytes.
    fn sub(&self, out: &mut Vec<u8>, t: u32, data: &[u8]) {
        if !data.is_empty() && data.len() <= 4 {
            let first = ((data.len() as u32) << 16) | t;
            out.extend(self.u32(first));
            let mut d = data.to_vec();
            d.resize(4, 0);
            out.extend(d);
        } else {
            self.tag(out, t, data.len());
            out.extend_from_slice(data);
            out.resize(out.len() + (8 - data.len() % 8) % 8, 0);
        }
    }

    fn matrix_body(&self, v: &Var) -> Vec<u8> {
        let mut b = Vec::new();
        let (class, complex) = match &v.body {
            Body::Numeric { class, complex, .. } => (*class, *complex),
            Body::Char(_) => (CHAR, false),
            Body::Cell => (CELL, false),
        };
        let mut flags = self.u32(u32::from(class) | if complex { 0x0800 } else { 0 }).to_vec();
        flags.extend(self.u32(0));
        self.sub(&mut b, MI_UINT32, &flags);
        let dims: Vec<u8> = v.dims.iter().flat_map(|d| self.u32(*d as u32)).collect();
        self.sub(&mut b, MI_INT32, &dims);
        self.sub(&mut b, MI_INT8, v.name.as_bytes());
        match &v.body {
            Body::Numeric { data, complex, .. } => {
                let bytes = data.bytes(self.be);
                self.sub(&mut b, data.mi_type(), &bytes);
                if *complex {
                    self.sub(&mut b, data.mi_type(), &bytes);
                }
            }
            Body::Char(s) => {
                let bytes: Vec<u8> =
                    s.encode_utf16().flat_map(|c| if self.be { c.to_be_bytes() } else { c.to_le_bytes() }).collect();
                self.sub(&mut b, MI_UINT16, &bytes);
            }
            Body::Cell => self.tag(&mut b, MI_MATRIX, 0),
        }
        b
    }
}

/// Encodes `vars` as a MAT v5 file.
pub fn write(vars: &[Var], opt: Options) -> Vec<u8> {
    let w = W { be: opt.big_endian };
    let mut out = Vec::new();
    let text = format!("MATLAB 5.0 MAT-file, written by the nlos test suite{}", " ".repeat(116));
    out.extend_from_slice(&text.as_bytes()[..116]);
    out.extend([0u8; 8]);
    out.extend(if opt.big_endian { 0x0100u16.to_be_bytes() } else { 0x0100u16.to_le_bytes() });
    out.extend(if opt.big_endian { *b"MI" } else { *b"IM" });
    for v in vars {
        let body = w.matrix_body(v);
        let mut element = Vec::new();
        w.tag(&mut element, MI_MATRIX, body.len());
        element.extend(body);
        if opt.compress {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&element).expect("in-memory zlib");
            let c = z.finish().expect("in-memory zlib");
            w.tag(&mut out, MI_COMPRESSED, c.len());
            out.extend(c);
        } else {
            out.extend(element);
        }
    }
    out
}
