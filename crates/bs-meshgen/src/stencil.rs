//! The stencils of isosurface stuffing: the part of a tetrahedron on the negative side of a
//! level set, given the signs of its vertices (−, 0, +) and the cut points on its (−, +)
//! edges, as tetrahedra.
//!
//! The negative part of a tetrahedron is a tetrahedron (one negative vertex), a pyramid
//! (two negative, one zero, one positive), a triangular prism (two negative and two
//! positive, or three negative and one positive) or the whole tetrahedron (no positive
//! vertex). Quadrilateral faces are split by a diagonal chosen from the *face alone*
//! ([`Cutter::face_diagonal`]), so two tetrahedra sharing the face split it the same way and
//! the mesh is conforming. A prism whose three diagonals turn the same way (a Schönhardt
//! twist) cannot be split into 3 tetrahedra; the rules used here avoid it (see the
//! `stuffing` module above this one), and a Steiner point at the prism's centroid is the
//! fallback.

use nalgebra::Point3;

/// Sign of the level-set function at a vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sign {
    /// Inside.
    Neg,
    /// On the surface (a warped lattice vertex or a cut point).
    Zero,
    /// Outside.
    Pos,
}

impl Sign {
    /// The sign of a value.
    #[inline]
    pub fn of(f: f64) -> Sign {
        if f < 0.0 {
            Sign::Neg
        } else if f > 0.0 {
            Sign::Pos
        } else {
            Sign::Zero
        }
    }

    /// The opposite side.
    #[inline]
    pub fn flip(self) -> Sign {
        match self {
            Sign::Neg => Sign::Pos,
            Sign::Pos => Sign::Neg,
            Sign::Zero => Sign::Zero,
        }
    }
}

/// What the stencils need to know about the nodes and the cut.
pub trait Cutter {
    /// Id of the cut point on the edge `a`–`b` (order irrelevant).
    fn cut(&self, a: u32, b: u32) -> u32;
    /// For a face whose vertices `na`, `nb` are on the kept side and `p` on the other, the
    /// kept part is the quadrilateral (`na`, `nb`, cut(`nb`,`p`), cut(`na`,`p`)). True when
    /// it is split by the diagonal `na`–cut(`nb`,`p`). Must satisfy
    /// `face_diagonal(na, nb, p) == !face_diagonal(nb, na, p)` and depend on the face only.
    fn face_diagonal(&self, na: u32, nb: u32, p: u32) -> bool;
    /// Preferred diagonal of a quadrilateral inside a tetrahedron (the isosurface quad of
    /// the two–two case): true for `q[0]`–`q[2]`.
    fn free_diagonal(&self, q: [u32; 4]) -> bool;
    /// Position of node `v`.
    fn pos(&self, v: u32) -> Point3<f64>;
}

/// Ids at or above this are Steiner points local to one [`Out`].
pub const STEINER: u32 = 1 << 31;

/// Tetrahedra produced by the stencils, positively oriented, with any Steiner points.
#[derive(Debug, Default, Clone)]
pub struct Out {
    /// Tetrahedra as node ids (ids ≥ [`STEINER`] index [`Out::steiner`]).
    pub tets: Vec<[u32; 4]>,
    /// Positions of Steiner points.
    pub steiner: Vec<Point3<f64>>,
}

impl Out {
    fn pos(&self, c: &impl Cutter, v: u32) -> Point3<f64> {
        if v >= STEINER { self.steiner[(v - STEINER) as usize] } else { c.pos(v) }
    }

    /// Appends a tetrahedron, swapping two nodes if it is negatively oriented.
    pub fn emit(&mut self, c: &impl Cutter, mut t: [u32; 4]) {
        let p = t.map(|v| self.pos(c, v));
        if (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0])) < 0.0 {
            t.swap(2, 3);
        }
        self.tets.push(t);
    }
}

/// Emits the tetrahedra of the negative part of tetrahedron `v` with signs `s`. `free`
/// forces the diagonal of the isosurface quad in the two–two case (true: first cut of the
/// first negative vertex to the second cut of the second, see the code).
pub fn fill_negative(
    v: [u32; 4],
    s: [Sign; 4],
    free: Option<bool>,
    c: &impl Cutter,
    out: &mut Out,
) {
    let mut neg = [0u32; 4];
    let mut pos = [0u32; 4];
    let mut zero = [0u32; 4];
    let (mut nn, mut np, mut nz) = (0, 0, 0);
    for i in 0..4 {
        match s[i] {
            Sign::Neg => {
                neg[nn] = v[i];
                nn += 1;
            }
            Sign::Pos => {
                pos[np] = v[i];
                np += 1;
            }
            Sign::Zero => {
                zero[nz] = v[i];
                nz += 1;
            }
        }
    }
    if nn == 0 {
        return;
    }
    if np == 0 {
        out.emit(c, v);
        return;
    }
    match (nn, np) {
        (1, _) => {
            // A tetrahedron: the negative vertex, the zeros and the cut points.
            let n = neg[0];
            let mut t = [n; 4];
            let mut k = 1;
            for &z in &zero[..nz] {
                t[k] = z;
                k += 1;
            }
            for &p in &pos[..np] {
                t[k] = c.cut(n, p);
                k += 1;
            }
            out.emit(c, t);
        }
        (2, 1) => {
            // A pyramid: apex the zero vertex, base the quadrilateral of face (n1, n2, p).
            let (n1, n2, p, z) = (neg[0], neg[1], pos[0], zero[0]);
            let (c1, c2) = (c.cut(n1, p), c.cut(n2, p));
            if c.face_diagonal(n1, n2, p) {
                out.emit(c, [z, n1, n2, c2]);
                out.emit(c, [z, n1, c2, c1]);
            } else {
                out.emit(c, [z, n1, n2, c1]);
                out.emit(c, [z, n2, c2, c1]);
            }
        }
        (2, 2) => {
            let (n1, n2, p1, p2) = (neg[0], neg[1], pos[0], pos[1]);
            let (c11, c12, c21, c22) = (c.cut(n1, p1), c.cut(n1, p2), c.cut(n2, p1), c.cut(n2, p2));
            let q0 = c.face_diagonal(n1, n2, p1);
            let q2 = !c.face_diagonal(n1, n2, p2);
            let q1 = match free {
                Some(f) => f,
                None => {
                    let pref = c.free_diagonal([c11, c12, c22, c21]);
                    if q0 == q2 && pref == q0 { !pref } else { pref }
                }
            };
            prism([n1, c11, c12], [n2, c21, c22], [q0, q1, q2], c, out);
        }
        (3, 1) => {
            let p = pos[0];
            let n = [neg[0], neg[1], neg[2]];
            let cuts = n.map(|x| c.cut(x, p));
            let q = [0, 1, 2].map(|i| c.face_diagonal(n[i], n[(i + 1) % 3], p));
            prism(n, cuts, q, c, out);
        }
        _ => unreachable!("sign counts of a tetrahedron with a negative and a positive vertex"),
    }
}

/// The diagonal the two–two case would choose for its isosurface quad without `free`
/// (used to agree on one diagonal for both sides of an interface).
pub fn two_two_diagonals(v: [u32; 4], s: [Sign; 4], c: &impl Cutter) -> Option<(bool, bool, bool)> {
    let neg: Vec<u32> = (0..4).filter(|&i| s[i] == Sign::Neg).map(|i| v[i]).collect();
    let pos: Vec<u32> = (0..4).filter(|&i| s[i] == Sign::Pos).map(|i| v[i]).collect();
    if neg.len() != 2 || pos.len() != 2 {
        return None;
    }
    let q0 = c.face_diagonal(neg[0], neg[1], pos[0]);
    let q2 = !c.face_diagonal(neg[0], neg[1], pos[1]);
    let free = c.free_diagonal([
        c.cut(neg[0], pos[0]),
        c.cut(neg[0], pos[1]),
        c.cut(neg[1], pos[1]),
        c.cut(neg[1], pos[0]),
    ]);
    Some((q0, free, q2))
}

/// Splits the prism with bottom `a`, top `b` (vertical edges `a[i]`–`b[i]`) into
/// tetrahedra. `q[i]` gives the diagonal of side quad `i` = (`a[i]`, `a[i+1]`, `b[i+1]`,
/// `b[i]`): true for `a[i]`–`b[i+1]`, false for `a[i+1]`–`b[i]`.
pub fn prism(a: [u32; 3], b: [u32; 3], q: [bool; 3], c: &impl Cutter, out: &mut Out) {
    let Some(i) = (0..3).find(|&i| q[i] != q[(i + 1) % 3]) else {
        // Twisted: no split without a new vertex. Cone from the centroid over the 8
        // boundary triangles.
        let centre =
            a.iter().chain(&b).map(|&v| out.pos(c, v).coords).sum::<nalgebra::Vector3<f64>>() / 6.0;
        let s = STEINER + out.steiner.len() as u32;
        out.steiner.push(Point3::from(centre));
        out.emit(c, [s, a[0], a[1], a[2]]);
        out.emit(c, [s, b[0], b[1], b[2]]);
        for k in 0..3 {
            let l = (k + 1) % 3;
            if q[k] {
                out.emit(c, [s, a[k], a[l], b[l]]);
                out.emit(c, [s, a[k], b[l], b[k]]);
            } else {
                out.emit(c, [s, a[k], a[l], b[k]]);
                out.emit(c, [s, a[l], b[l], b[k]]);
            }
        }
        return;
    };
    let j = (i + 1) % 3;
    let m = (i + 2) % 3;
    // The vertex with two diagonals: a[j] if quad i uses a[j]–b[i] and quad j uses
    // a[j]–b[m]; otherwise b[j]. Cut off the opposite cap with it, leaving a pyramid over
    // quad m.
    let apex = if !q[i] && q[j] {
        out.emit(c, [a[j], b[0], b[1], b[2]]);
        a[j]
    } else {
        out.emit(c, [b[j], a[0], a[1], a[2]]);
        b[j]
    };
    // Quad m = (a[m], a[i], b[i], b[m]).
    if q[m] {
        out.emit(c, [apex, a[m], a[i], b[i]]);
        out.emit(c, [apex, a[m], b[i], b[m]]);
    } else {
        out.emit(c, [apex, a[m], a[i], b[m]]);
        out.emit(c, [apex, a[i], b[i], b[m]]);
    }
}
