//! The body-centred cubic (BCC) lattice of isosurface stuffing.
//!
//! Cubes of side `h` on an axis-aligned grid; the *black* vertices are the cube corners,
//! the *red* vertices the cube centres. Lattice edges are *long* (length `h`, joining two
//! vertices of the same colour along an axis) or *short* (length `h √3 / 2`, a centre to
//! one of its cube's corners). Every pair of face-adjacent cube centres with one of the 4
//! edges of their shared face spans one BCC tetrahedron (2 long and 4 short edges, all
//! dihedral angles 60° or 90°), 12 per cube, which tile space (Labelle & Shewchuk 2007).

use nalgebra::{Point3, Vector3};

/// An axis-aligned BCC lattice of `n` cubes of side `h` from `origin`.
#[derive(Debug, Clone)]
pub struct Bcc {
    /// World position of black vertex (0, 0, 0).
    pub origin: Point3<f64>,
    /// Cube side (the long edge length).
    pub h: f64,
    /// Number of cubes along x, y, z.
    pub n: [usize; 3],
    black: usize,
}

impl Bcc {
    /// The lattice of cubes of side `h` covering the box `lo..hi` with `pad` extra cubes on
    /// every side.
    pub fn covering(lo: Point3<f64>, hi: Point3<f64>, h: f64, pad: usize) -> Bcc {
        let n = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / h).ceil().max(1.0) as usize + 2 * pad);
        let centre = Point3::from((lo.coords + hi.coords) * 0.5);
        let half = Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64) * (0.5 * h);
        Bcc::new(centre - half, h, n)
    }

    /// A lattice with black vertex (0,0,0) at `origin`.
    pub fn new(origin: Point3<f64>, h: f64, n: [usize; 3]) -> Bcc {
        let black = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
        Bcc { origin, h, n, black }
    }

    /// Total number of lattice vertices (black then red).
    pub fn vertex_count(&self) -> usize {
        self.black + self.n[0] * self.n[1] * self.n[2]
    }

    /// Id of black vertex (i, j, k).
    #[inline]
    pub fn black(&self, i: usize, j: usize, k: usize) -> u32 {
        (i + (self.n[0] + 1) * (j + (self.n[1] + 1) * k)) as u32
    }

    /// Id of the red vertex (centre) of cube (i, j, k).
    #[inline]
    pub fn red(&self, i: usize, j: usize, k: usize) -> u32 {
        (self.black + i + self.n[0] * (j + self.n[1] * k)) as u32
    }

    /// Whether vertex `v` is a cube centre.
    #[inline]
    pub fn is_red(&self, v: u32) -> bool {
        v as usize >= self.black
    }

    /// Lattice index (i, j, k) of vertex `v` and its colour (true = red).
    #[inline]
    pub fn coords(&self, v: u32) -> ([usize; 3], bool) {
        let v = v as usize;
        if v < self.black {
            let (nx, ny) = (self.n[0] + 1, self.n[1] + 1);
            ([v % nx, (v / nx) % ny, v / (nx * ny)], false)
        } else {
            let r = v - self.black;
            let (nx, ny) = (self.n[0], self.n[1]);
            ([r % nx, (r / nx) % ny, r / (nx * ny)], true)
        }
    }

    /// World position of lattice vertex `v`.
    #[inline]
    pub fn position(&self, v: u32) -> Point3<f64> {
        let (c, red) = self.coords(v);
        let o = if red { 0.5 } else { 0.0 };
        self.origin + Vector3::new(c[0] as f64 + o, c[1] as f64 + o, c[2] as f64 + o) * self.h
    }

    /// Whether the lattice edge `a`–`b` is long (same colour).
    #[inline]
    pub fn is_long(&self, a: u32, b: u32) -> bool {
        self.is_red(a) == self.is_red(b)
    }

    /// Parity of a vertex's lattice index, `(i + j + k)` even. The two ends of a long edge
    /// always differ in parity.
    #[inline]
    pub fn is_even(&self, v: u32) -> bool {
        let (c, _) = self.coords(v);
        (c[0] + c[1] + c[2]).is_multiple_of(2)
    }

    /// The lattice edges leaving vertex `v` towards "later" neighbours (each edge listed
    /// once over all vertices): 3 long edges, plus the 8 short edges of a centre. Returns
    /// the neighbours and how many there are.
    pub fn forward_edges(&self, v: u32) -> ([u32; 11], usize) {
        let mut out = [0u32; 11];
        let mut k = 0;
        let (c, red) = self.coords(v);
        let lim = if red { self.n } else { self.n.map(|x| x + 1) };
        for a in 0..3 {
            if c[a] + 1 < lim[a] {
                let mut d = c;
                d[a] += 1;
                out[k] =
                    if red { self.red(d[0], d[1], d[2]) } else { self.black(d[0], d[1], d[2]) };
                k += 1;
            }
        }
        if red {
            for m in 0..8 {
                out[k] = self.black(c[0] + (m & 1), c[1] + ((m >> 1) & 1), c[2] + ((m >> 2) & 1));
                k += 1;
            }
        }
        (out, k)
    }

    /// The 12 (or fewer at the lattice border) tetrahedra owned by cube (i, j, k): those of
    /// its +x, +y and +z faces, as (centre, neighbour centre, face corner, next face corner).
    pub fn cube_tets(&self, c: [usize; 3], out: &mut Vec<[u32; 4]>) {
        out.clear();
        let r1 = self.red(c[0], c[1], c[2]);
        for a in 0..3 {
            if c[a] + 1 >= self.n[a] {
                continue;
            }
            let mut d = c;
            d[a] += 1;
            let r2 = self.red(d[0], d[1], d[2]);
            let (b, e) = ((a + 1) % 3, (a + 2) % 3);
            let corner = |u: usize, w: usize| {
                let mut q = [0usize; 3];
                q[a] = c[a] + 1;
                q[b] = c[b] + u;
                q[e] = c[e] + w;
                self.black(q[0], q[1], q[2])
            };
            let ring = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            for m in 0..4 {
                out.push([r1, r2, ring[m], ring[(m + 1) % 4]]);
            }
        }
    }

    /// Number of cubes.
    pub fn cube_count(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    /// Index (i, j, k) of cube number `c` (x fastest).
    pub fn cube(&self, c: usize) -> [usize; 3] {
        [c % self.n[0], (c / self.n[0]) % self.n[1], c / (self.n[0] * self.n[1])]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::dihedral_angles;

    /// The BCC tetrahedra tile the interior cubes: total volume (n−1)³ h³ worth of the
    /// cube-centre dual, 60°/90° dihedral angles, edge lengths h and h√3/2.
    #[test]
    fn bcc_tets_have_the_closed_form_shape() {
        let b = Bcc::new(Point3::origin(), 2.0, [3, 3, 3]);
        let mut tets = Vec::new();
        let mut all = Vec::new();
        for c in 0..b.cube_count() {
            b.cube_tets(b.cube(c), &mut tets);
            all.extend_from_slice(&tets);
        }
        // Interior faces: 3 axes × 2 × 3 × 3 = 54, 4 tets each.
        assert_eq!(all.len(), 216);
        for t in &all {
            let p = t.map(|v| b.position(v));
            let vol = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0])).abs() / 6.0;
            // V = h³/12 for h = 2.
            assert!((vol - 8.0 / 12.0).abs() < 1e-12);
            for a in dihedral_angles(&p) {
                let deg = a.to_degrees();
                assert!((deg - 60.0).abs() < 1e-9 || (deg - 90.0).abs() < 1e-9, "{deg}");
            }
            assert!(b.is_long(t[0], t[1]) && b.is_long(t[2], t[3]));
            assert!(b.is_even(t[2]) != b.is_even(t[3]));
        }
    }
}
