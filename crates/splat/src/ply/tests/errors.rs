//! Malformed PLY input and bad data to write: errors naming the file, element, property or
//! vertex, never a panic, nothing half-written.

use super::*;

/// Guards the error naming the missing property and what is present.
#[test]
fn missing_property_error_names_it() {
    let props: Vec<String> = float_props(0)
        .into_iter()
        .filter(|p| p != "float opacity")
        .collect();
    let err = parse_ply(&header("ascii", &[("vertex", 0, props)])).unwrap_err();
    assert!(matches!(&err, PlyError::MissingProperty { name, .. } if name == "opacity"));
    let msg = err.to_string();
    assert!(
        msg.contains("`opacity`") && msg.contains("scale_0"),
        "{msg}"
    );
}

/// Guards the truncated-binary error naming the first incomplete vertex.
#[test]
fn truncated_binary_error() {
    let bytes = to_ply_bytes(&sample(3, 0));
    let err = parse_ply(&bytes[..bytes.len() - 5]).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("vertex 2 of 3") && msg.contains("expected 68 bytes"),
        "{msg}"
    );
}

/// Guards the truncated-ascii error naming the last line read.
#[test]
fn truncated_ascii_error() {
    let text = encode(&sample(3, 0), Format::Ascii);
    let text = String::from_utf8(text)
        .unwrap()
        .replace("vertex 3", "vertex 4");
    let msg = parse_ply(text.as_bytes()).unwrap_err().to_string();
    assert!(
        msg.contains("vertex 3 of 4") && msg.contains("line"),
        "{msg}"
    );
}

/// Guards that NaN/Inf (and doubles beyond f32) are rejected with the
/// property and vertex named, in binary and ascii.
#[test]
fn non_finite_error_names_property_and_vertex() {
    let mut g = sample(3, 0);
    g.opacity_logit[1] = f32::NAN;
    for bytes in [to_ply_bytes(&g), encode(&g, Format::Ascii)] {
        let err = parse_ply(&bytes).unwrap_err();
        assert!(
            matches!(&err, PlyError::NonFinite { property, vertex: 1, .. } if property == "opacity"),
            "{err}"
        );
    }
    let mut g = sample(2, 0);
    g.rotations[0][2] = f32::INFINITY;
    let err = parse_ply(&encode(&g, Format::Ascii))
        .unwrap_err()
        .to_string();
    assert!(err.contains("rot_2") && err.contains("vertex 0"), "{err}");
    let names = property_names(0);
    let props: Vec<(&str, &str)> = std::iter::once(("double", "x"))
        .chain(names[1..].iter().map(|n| ("float", n.as_str())))
        .filter(|(_, n)| !n.starts_with('n'))
        .collect();
    let mut bytes = header("binary_little_endian", &[("vertex", 1, typed(&props))]);
    bytes.extend(1e300f64.to_le_bytes());
    bytes.extend(std::iter::repeat_n(0u8, 4 * (props.len() - 1)));
    assert!(matches!(
        parse_ply(&bytes),
        Err(PlyError::NonFinite { vertex: 0, .. })
    ));
}

/// Guards against panics or vague errors on non-PLY and broken headers.
#[test]
fn garbage_and_empty_file_rejected() {
    for bytes in [
        &b""[..],
        b"hello world",
        b"\xff\x00\x13ply",
        b"plyx\n",
        b"PLY\n",
    ] {
        assert!(
            matches!(parse_ply(bytes), Err(PlyError::NotPly)),
            "{bytes:?}"
        );
    }
    let r = parse_ply(b"ply\nformat ascii 1.0\nelement vertex 0\n");
    assert!(matches!(r, Err(PlyError::UnterminatedHeader)));
    let r = parse_ply(b"ply\nformat ascii 2.0\nend_header\n");
    assert!(matches!(r, Err(PlyError::UnsupportedFormat { .. })));
    let msg = parse_ply(b"ply\nformat ascii 1.0\nelement vertex abc\nend_header\n")
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("line 3") && msg.contains("element vertex abc"),
        "{msg}"
    );
    let r = parse_ply(b"ply\nformat ascii 1.0\nproperty float x\nend_header\n");
    assert!(matches!(
        r,
        Err(PlyError::MalformedHeader { line_no: 3, .. })
    ));
    let r = parse_ply(b"ply\nelement vertex 0\nend_header\n");
    assert!(matches!(r, Err(PlyError::MalformedHeader { .. })));
    let r = parse_ply(b"ply\nformat ascii 1.0\nelement face 0\nend_header\n");
    assert!(matches!(r, Err(PlyError::MissingVertexElement { .. })));
}

/// Guards against panics on arbitrary corruption: every prefix and a set of
/// byte substitutions of valid files must give Ok or Err, never a panic.
#[test]
fn corrupted_files_never_panic() {
    let g = sample(2, 1);
    for bytes in [to_ply_bytes(&g), encode(&g, Format::Ascii)] {
        for cut in 0..=bytes.len() {
            let _ = parse_ply(&bytes[..cut]);
        }
        for pos in 0..bytes.len() {
            for b in [0u8, b'9', b'\n', b' ', 0xff] {
                let mut c = bytes.clone();
                c[pos] = b;
                let _ = parse_ply(&c);
            }
        }
    }
}

/// Guards against allocating for a declared count the data cannot hold.
#[test]
fn huge_declared_count_with_tiny_file() {
    for count in [usize::MAX, 1usize << 40] {
        for format in ["binary_little_endian", "ascii"] {
            let mut bytes = header(format, &[("vertex", count, float_props(0))]);
            bytes.extend_from_slice(b"0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n");
            let err = parse_ply(&bytes).unwrap_err();
            assert!(matches!(err, PlyError::Truncated { .. }), "{err}");
        }
    }
    let mut bytes = header(
        "binary_little_endian",
        &[
            ("face", usize::MAX, vec!["list uint int idx".into()]),
            ("vertex", 1, float_props(0)),
        ],
    );
    bytes.extend_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(parse_ply(&bytes), Err(PlyError::Truncated { .. })));
}

/// Guards against silently dropping SH coefficients after a gap.
#[test]
fn f_rest_gap_rejected() {
    let mut props = float_props(0);
    props.extend(["float f_rest_0".to_owned(), "float f_rest_2".into()]);
    let err = parse_ply(&header("ascii", &[("vertex", 0, props)])).unwrap_err();
    assert!(
        matches!(err, PlyError::NonContiguousFRest { missing: 1, .. }),
        "{err}"
    );
}

/// Guards the ascii value-count and number-syntax errors.
#[test]
fn ascii_value_errors() {
    let text = String::from_utf8(encode(&sample(2, 0), Format::Ascii)).unwrap();
    let (head, body) = text.split_once("end_header\n").unwrap();
    let lines: Vec<&str> = body.lines().collect();
    let extra = format!("{head}end_header\n{}\n{} 5\n", lines[0], lines[1]);
    assert!(matches!(
        parse_ply(extra.as_bytes()),
        Err(PlyError::AsciiExtraValues { vertex: 1, .. })
    ));
    let short = format!("{head}end_header\n{}\n1 2 3\n", lines[0]);
    let msg = parse_ply(short.as_bytes()).unwrap_err().to_string();
    assert!(msg.contains("vertex 1") && msg.contains("`nx`"), "{msg}");
    let bad = format!("{head}end_header\n{}\nabc{}\n", lines[0], lines[1]);
    let err = parse_ply(bad.as_bytes()).unwrap_err();
    assert!(matches!(&err, PlyError::AsciiNumber { property, vertex: 1, .. } if property == "x"));
}

/// Guards write_ply refusing data it could not read back, and leaving an
/// existing file and no temp file behind when it does.
#[test]
fn write_ply_rejects_bad_data_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.ply");
    std::fs::write(&path, b"old").unwrap();
    let mut g = sample(2, 0);
    g.log_scales[1][0] = f32::NAN;
    let err = write_ply(&path, &g).unwrap_err().to_string();
    assert!(err.contains("scale_0") && err.contains("vertex 1"), "{err}");
    g = sample(2, 0);
    g.rotations.pop();
    assert!(matches!(
        write_ply(&path, &g),
        Err(PlyError::Inconsistent(_))
    ));
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let missing = dir.path().join("no/such/dir/scene.ply");
    let err = write_ply(&missing, &sample(1, 0)).unwrap_err();
    assert!(matches!(err, PlyError::Io { .. }));
}

/// Guards that a missing input file error names the path.
#[test]
fn read_missing_file_names_path() {
    let err = read_ply(Path::new("/nonexistent/dir/scene.ply")).unwrap_err();
    assert!(
        err.to_string().contains("/nonexistent/dir/scene.ply"),
        "{err}"
    );
}
