//! A minimal pickle writer for what ACT's `dataset_stats.pkl` holds: a dict from str to float64
//! numpy arrays, in exactly the form numpy itself pickles an array (protocol 3, via
//! `numpy.core.multiarray._reconstruct`, which numpy 1.x and 2.x both load).
//!
//! Writing it here keeps the build free of Python; the tests load it with `pickle.load`.

/// A float64 array: shape and row-major values.
pub struct Array {
    pub shape: Vec<usize>,
    pub values: Vec<f64>,
}

fn global(out: &mut Vec<u8>, module: &str, name: &str) {
    out.push(b'c');
    out.extend_from_slice(module.as_bytes());
    out.push(b'\n');
    out.extend_from_slice(name.as_bytes());
    out.push(b'\n');
}

fn int(out: &mut Vec<u8>, v: i64) {
    if (0..256).contains(&v) {
        out.push(b'K');
        out.push(v as u8);
    } else {
        out.push(b'J');
        out.extend_from_slice(&(v as i32).to_le_bytes());
    }
}

fn unicode(out: &mut Vec<u8>, s: &str) {
    out.push(b'X');
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

fn tuple_of_ints(out: &mut Vec<u8>, values: &[usize]) {
    match values.len() {
        0 => out.push(b')'),
        1..=3 => {
            for &v in values {
                int(out, v as i64);
            }
            out.push([b'\x85', b'\x86', b'\x87'][values.len() - 1]);
        }
        _ => {
            out.push(b'(');
            for &v in values {
                int(out, v as i64);
            }
            out.push(b't');
        }
    }
}

fn array(out: &mut Vec<u8>, a: &Array) {
    global(out, "numpy.core.multiarray", "_reconstruct");
    global(out, "numpy", "ndarray");
    tuple_of_ints(out, &[0]);
    out.extend_from_slice(b"C\x01b"); // SHORT_BINBYTES b"b"
    out.push(b'\x87'); // TUPLE3
    out.push(b'R'); // REDUCE: an empty ndarray
    out.push(b'(');
    int(out, 1);
    tuple_of_ints(out, &a.shape);
    // dtype('f8', False, True) with its state (3, '<', None, None, None, -1, -1, 0)
    global(out, "numpy", "dtype");
    unicode(out, "f8");
    out.extend_from_slice(b"\x89\x88\x87R");
    out.push(b'(');
    int(out, 3);
    unicode(out, "<");
    out.extend_from_slice(b"NNN");
    int(out, -1);
    int(out, -1);
    int(out, 0);
    out.extend_from_slice(b"tb");
    out.push(b'\x89'); // not Fortran order
    let bytes: Vec<u8> = a.values.iter().flat_map(|v| v.to_le_bytes()).collect();
    out.push(b'B');
    out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&bytes);
    out.extend_from_slice(b"tb"); // the state tuple, BUILD
}

/// Pickles `{name: array}` in the given order.
pub fn dict_of_arrays(items: &[(String, Array)]) -> Vec<u8> {
    let mut out = vec![0x80, 3, b'}'];
    if !items.is_empty() {
        out.push(b'(');
        for (name, a) in items {
            unicode(&mut out, name);
            array(&mut out, a);
        }
        out.push(b'u');
    }
    out.push(b'.');
    out
}
