// Long file: each representation's conversion to and from the matrix, and their tests, side by side.
//! Rotations in the representations robot datasets store (axis-angle, quaternions in either
//! order, Euler angles, matrices, the continuous 6D representation) and the conversions between
//! them, through the 3x3 rotation matrix.
//!
//! Conventions follow the codebases' own math: Euler sequences as `scipy.spatial.transform`
//! names them (lowercase extrinsic, uppercase intrinsic), a matrix stored row-major, and the 6D
//! representation as pytorch3d's `matrix_to_rotation_6d` (the first two ROWS, which Diffusion
//! Policy and UMI use) or as Zhou et al. (the first two columns). Quaternions come out with
//! `w >= 0`.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A 3x3 rotation matrix, row-major.
pub type Matrix = [[f64; 3]; 3];

/// How a rotation is stored in a slice of a channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RotationKind {
    /// A rotation vector: the axis times the angle in radians (3 values).
    AxisAngle,
    /// A unit quaternion, scalar first (4 values).
    QuaternionWxyz,
    /// A unit quaternion, scalar last, as scipy and ROS store it (4 values).
    QuaternionXyzw,
    /// Three angles in radians, in the axis order of `convention` (3 values).
    Euler,
    /// The 3x3 matrix, row-major (9 values).
    Matrix,
    /// The first two rows of the matrix (pytorch3d), or its first two columns with
    /// `layout = "columns"` (6 values).
    #[serde(rename = "rotation_6d")]
    Rotation6d,
}

impl RotationKind {
    pub fn name(self) -> &'static str {
        match self {
            RotationKind::AxisAngle => "axis_angle",
            RotationKind::QuaternionWxyz => "quaternion_wxyz",
            RotationKind::QuaternionXyzw => "quaternion_xyzw",
            RotationKind::Euler => "euler",
            RotationKind::Matrix => "matrix",
            RotationKind::Rotation6d => "rotation_6d",
        }
    }

    /// Values per rotation.
    pub fn width(self) -> usize {
        match self {
            RotationKind::AxisAngle | RotationKind::Euler => 3,
            RotationKind::QuaternionWxyz | RotationKind::QuaternionXyzw => 4,
            RotationKind::Matrix => 9,
            RotationKind::Rotation6d => 6,
        }
    }
}

/// Which half of the matrix the 6D representation keeps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Layout6d {
    /// The first two rows (pytorch3d's `matrix_to_rotation_6d`; Diffusion Policy, UMI).
    #[default]
    Rows,
    /// The first two columns (Zhou et al.).
    Columns,
}

impl Layout6d {
    pub fn name(self) -> &'static str {
        match self {
            Layout6d::Rows => "rows",
            Layout6d::Columns => "columns",
        }
    }
}

/// An Euler sequence: three axes (0 = x, 1 = y, 2 = z), extrinsic or intrinsic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Euler {
    pub axes: [usize; 3],
    pub intrinsic: bool,
}

impl Euler {
    /// Parses scipy's `seq`: three of `xyz` (extrinsic) or of `XYZ` (intrinsic), no axis twice
    /// in a row.
    pub fn parse(seq: &str) -> Result<Euler, String> {
        let chars: Vec<char> = seq.chars().collect();
        let bad = || {
            format!("`{seq}` is not an Euler sequence: three of x, y, z (extrinsic) or of X, Y, Z (intrinsic), no axis twice in a row, as scipy's `from_euler` takes")
        };
        if chars.len() != 3 {
            return Err(bad());
        }
        let intrinsic = chars[0].is_ascii_uppercase();
        let mut axes = [0usize; 3];
        for (a, c) in axes.iter_mut().zip(&chars) {
            if c.is_ascii_uppercase() != intrinsic {
                return Err(bad());
            }
            *a = match c.to_ascii_lowercase() {
                'x' => 0,
                'y' => 1,
                'z' => 2,
                _ => return Err(bad()),
            };
        }
        if axes[0] == axes[1] || axes[1] == axes[2] {
            return Err(bad());
        }
        Ok(Euler { axes, intrinsic })
    }
}

/// How far from a rotation a stored value may be (a quaternion's norm from 1, a matrix's
/// `R Rᵀ` from the identity, a 6D vector's norms and dot product).
pub const TOLERANCE: f64 = 1e-2;

/// Why a stored value is not a rotation.
pub type NotRotation = String;

fn mul(a: &Matrix, b: &Matrix) -> Matrix {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The transpose (the inverse of a rotation).
pub fn transpose(a: &Matrix) -> Matrix {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = a[j][i];
        }
    }
    m
}

/// `a @ b`.
pub fn matmul(a: &Matrix, b: &Matrix) -> Matrix {
    mul(a, b)
}

/// `a @ v`.
pub fn apply(a: &Matrix, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The rotation about one axis by `angle` (active, right-handed).
fn elementary(axis: usize, angle: f64) -> Matrix {
    let (s, c) = angle.sin_cos();
    match axis {
        0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    }
}

fn from_quaternion(w: f64, x: f64, y: f64, z: f64) -> Result<Matrix, NotRotation> {
    let n = (w * w + x * x + y * y + z * z).sqrt();
    if !n.is_finite() || (n - 1.0).abs() > TOLERANCE {
        return Err(format!(
            "a quaternion of norm {n:.4} (a rotation's is 1, within {TOLERANCE})"
        ));
    }
    let (w, x, y, z) = (w / n, x / n, y / n, z / n);
    Ok([
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ])
}

fn from_axis_angle(v: &[f64]) -> Matrix {
    let t2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    let t = t2.sqrt();
    // R = I + a [v]x + b [v]x², with a = sin t / t and b = (1 - cos t) / t² (series near 0).
    let (a, b) = if t < 1e-6 {
        (1.0 - t2 / 6.0, 0.5 - t2 / 24.0)
    } else {
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    let k = [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]];
    let k2 = mul(&k, &k);
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = f64::from(u8::from(i == j)) + a * k[i][j] + b * k2[i][j];
        }
    }
    m
}

fn from_6d(v: &[f64], layout: Layout6d) -> Result<Matrix, NotRotation> {
    let a1 = [v[0], v[1], v[2]];
    let a2 = [v[3], v[4], v[5]];
    let (n1, n2) = (norm(&a1), norm(&a2));
    let dot: f64 = (0..3).map(|i| a1[i] * a2[i]).sum();
    if !(n1.is_finite() && n2.is_finite())
        || (n1 - 1.0).abs() > TOLERANCE
        || (n2 - 1.0).abs() > TOLERANCE
        || dot.abs() > TOLERANCE
    {
        return Err(format!(
            "a 6D rotation whose vectors have norms {n1:.4} and {n2:.4} and dot product {dot:.4} (a rotation's are unit and orthogonal, within {TOLERANCE})"
        ));
    }
    // pytorch3d's Gram-Schmidt: b1 = a1 / |a1|, b2 = a2 - (b1·a2) b1 normalized, b3 = b1 × b2.
    let b1 = a1.map(|x| x / n1);
    let d: f64 = (0..3).map(|i| b1[i] * a2[i]).sum();
    let b2 = [0, 1, 2].map(|i| a2[i] - d * b1[i]);
    let m2 = norm(&b2);
    let b2 = b2.map(|x| x / m2);
    let b3 = cross(b1, b2);
    let rows = [b1, b2, b3];
    Ok(match layout {
        Layout6d::Rows => rows,
        Layout6d::Columns => transpose(&rows),
    })
}

fn check_matrix(m: &Matrix) -> Result<(), NotRotation> {
    let p = mul(m, &transpose(m));
    let off = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| (p[i][j] - f64::from(u8::from(i == j))).abs())
        .fold(0.0f64, f64::max);
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if !off.is_finite() || off > TOLERANCE || det < 0.0 {
        return Err(format!(
            "a matrix {} from a rotation (R Rᵀ off the identity by {off:.4}, determinant {det:.4})",
            if det < 0.0 {
                "that mirrors, far"
            } else {
                "far"
            }
        ));
    }
    Ok(())
}

/// The rotation matrix of one stored value (`v.len() == kind.width()`).
pub fn to_matrix(
    kind: RotationKind,
    v: &[f64],
    euler: Option<Euler>,
    layout: Layout6d,
) -> Result<Matrix, NotRotation> {
    match kind {
        RotationKind::AxisAngle => {
            if v.iter().any(|x| !x.is_finite()) {
                return Err("an axis-angle vector that is not finite".into());
            }
            Ok(from_axis_angle(v))
        }
        RotationKind::QuaternionWxyz => from_quaternion(v[0], v[1], v[2], v[3]),
        RotationKind::QuaternionXyzw => from_quaternion(v[3], v[0], v[1], v[2]),
        RotationKind::Euler => {
            let e = euler.expect("an euler rotation has its convention (checked by the plan)");
            let r = [0, 1, 2].map(|i| elementary(e.axes[i], v[i]));
            // Extrinsic: the first rotation is applied first about the fixed axes (R3 R2 R1);
            // intrinsic: about the moving axes (R1 R2 R3).
            Ok(if e.intrinsic {
                mul(&mul(&r[0], &r[1]), &r[2])
            } else {
                mul(&mul(&r[2], &r[1]), &r[0])
            })
        }
        RotationKind::Matrix => {
            let m = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
            check_matrix(&m)?;
            Ok(m)
        }
        RotationKind::Rotation6d => from_6d(v, layout),
    }
}

/// The unit quaternion `(w, x, y, z)` of a rotation matrix, with `w >= 0` (Shepperd's method:
/// the largest of the four candidates is taken from the diagonal, the others from it).
pub fn quaternion(m: &Matrix) -> [f64; 4] {
    let t = m[0][0] + m[1][1] + m[2][2];
    let q = if t >= m[0][0] && t >= m[1][1] && t >= m[2][2] {
        let w = 0.5 * (1.0 + t).max(0.0).sqrt();
        let f = 0.25 / w;
        [
            w,
            (m[2][1] - m[1][2]) * f,
            (m[0][2] - m[2][0]) * f,
            (m[1][0] - m[0][1]) * f,
        ]
    } else if m[0][0] >= m[1][1] && m[0][0] >= m[2][2] {
        let x = 0.5 * (1.0 + m[0][0] - m[1][1] - m[2][2]).max(0.0).sqrt();
        let f = 0.25 / x;
        [
            (m[2][1] - m[1][2]) * f,
            x,
            (m[0][1] + m[1][0]) * f,
            (m[0][2] + m[2][0]) * f,
        ]
    } else if m[1][1] >= m[2][2] {
        let y = 0.5 * (1.0 - m[0][0] + m[1][1] - m[2][2]).max(0.0).sqrt();
        let f = 0.25 / y;
        [
            (m[0][2] - m[2][0]) * f,
            (m[0][1] + m[1][0]) * f,
            y,
            (m[1][2] + m[2][1]) * f,
        ]
    } else {
        let z = 0.5 * (1.0 - m[0][0] - m[1][1] + m[2][2]).max(0.0).sqrt();
        let f = 0.25 / z;
        [
            (m[1][0] - m[0][1]) * f,
            (m[0][2] + m[2][0]) * f,
            (m[1][2] + m[2][1]) * f,
            z,
        ]
    };
    let n = norm(&q);
    let s = if q[0] < 0.0 { -1.0 / n } else { 1.0 / n };
    q.map(|x| x * s)
}

/// Writes the rotation `m` as `kind` into `out` (`out.len() == kind.width()`). Euler angles
/// are not a target (the plan refuses them): a discontinuous representation to train on.
pub fn from_matrix(kind: RotationKind, m: &Matrix, layout: Layout6d, out: &mut [f64]) {
    match kind {
        RotationKind::AxisAngle => {
            let [w, x, y, z] = quaternion(m);
            let s = (x * x + y * y + z * z).sqrt();
            let angle = 2.0 * s.atan2(w);
            // angle / s tends to 2 / w as the rotation vanishes.
            let f = if s < 1e-12 { 2.0 / w } else { angle / s };
            out.copy_from_slice(&[x * f, y * f, z * f]);
        }
        RotationKind::QuaternionWxyz => out.copy_from_slice(&quaternion(m)),
        RotationKind::QuaternionXyzw => {
            let [w, x, y, z] = quaternion(m);
            out.copy_from_slice(&[x, y, z, w]);
        }
        RotationKind::Matrix => {
            for (i, row) in m.iter().enumerate() {
                out[3 * i..3 * i + 3].copy_from_slice(row);
            }
        }
        RotationKind::Rotation6d => {
            let m = match layout {
                Layout6d::Rows => *m,
                Layout6d::Columns => transpose(m),
            };
            out[..3].copy_from_slice(&m[0]);
            out[3..6].copy_from_slice(&m[1]);
        }
        RotationKind::Euler => unreachable!("euler is not a conversion target"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Matrix, b: &Matrix) -> bool {
        (0..3).all(|i| (0..3).all(|j| (a[i][j] - b[i][j]).abs() < 1e-12))
    }

    #[test]
    fn every_kind_round_trips_through_the_matrix() {
        let m = from_axis_angle(&[0.3, -1.1, 0.7]);
        for kind in [
            RotationKind::AxisAngle,
            RotationKind::QuaternionWxyz,
            RotationKind::QuaternionXyzw,
            RotationKind::Matrix,
            RotationKind::Rotation6d,
        ] {
            for layout in [Layout6d::Rows, Layout6d::Columns] {
                let mut v = vec![0.0; kind.width()];
                from_matrix(kind, &m, layout, &mut v);
                let back = to_matrix(kind, &v, None, layout).unwrap();
                assert!(close(&m, &back), "{kind:?} {layout:?}");
            }
        }
    }

    #[test]
    fn rows_and_columns_differ_as_pytorch3d_and_zhou() {
        let m = from_axis_angle(&[0.2, 0.5, -0.4]);
        let (mut rows, mut cols) = ([0.0; 6], [0.0; 6]);
        from_matrix(RotationKind::Rotation6d, &m, Layout6d::Rows, &mut rows);
        from_matrix(RotationKind::Rotation6d, &m, Layout6d::Columns, &mut cols);
        assert_eq!(rows[..3], m[0]);
        assert_eq!(cols[..3], [m[0][0], m[1][0], m[2][0]]);
    }

    #[test]
    fn extrinsic_xyz_is_intrinsic_zyx_reversed() {
        let a = [0.3, -0.2, 1.2];
        let ext = to_matrix(
            RotationKind::Euler,
            &a,
            Some(Euler::parse("xyz").unwrap()),
            Layout6d::Rows,
        )
        .unwrap();
        let int = to_matrix(
            RotationKind::Euler,
            &[a[2], a[1], a[0]],
            Some(Euler::parse("ZYX").unwrap()),
            Layout6d::Rows,
        )
        .unwrap();
        assert!(close(&ext, &int));
        assert!(Euler::parse("xxy").is_err() && Euler::parse("xYz").is_err());
    }

    #[test]
    fn non_rotations_are_refused() {
        assert!(to_matrix(
            RotationKind::QuaternionWxyz,
            &[0.5, 0.5, 0.5, 0.2],
            None,
            Layout6d::Rows
        )
        .is_err());
        let mut m = [0.0; 9];
        m[0] = 2.0;
        m[4] = 1.0;
        m[8] = 1.0;
        assert!(to_matrix(RotationKind::Matrix, &m, None, Layout6d::Rows).is_err());
    }

    #[test]
    fn axis_angle_near_pi_and_zero() {
        for v in [[0.0, 0.0, 1e-9], [3.1, 0.0, 0.0], [0.0, 2.0, 2.0]] {
            let m = from_axis_angle(&v);
            let mut out = [0.0; 3];
            from_matrix(RotationKind::AxisAngle, &m, Layout6d::Rows, &mut out);
            assert!(close(&m, &from_axis_angle(&out)), "{v:?} -> {out:?}");
        }
    }
}
