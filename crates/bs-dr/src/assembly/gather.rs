//! The deterministic gather: every node sums its force slots in a fixed order on SIMD lanes.

use bs_mesh::Vector3;

use crate::kernels::simd::{BlockOp, Lanes};

use super::elements::Elements;

/// The gather of a run of nodes starting at `first`: each node's slots in `gather_slot`
/// order, tet slots then hex slots, every slot read as one vector of four (x, y, z and
/// the next value, ignored), summed in two interleaved partial sums (even and odd
/// positions; two independent add chains) added at the end. The order is fixed, so the
/// result does not depend on the thread count.
pub(super) struct Gather<'a> {
    pub(super) elements: &'a Elements,
    pub(super) first: usize,
    /// Flattened tet slots: slot `s` at `3s`.
    pub(super) tslots: &'a [f64],
    /// Flattened hex slots: hex slot `h` at `3h`.
    pub(super) hslots: &'a [f64],
    pub(super) forces: &'a mut [Vector3<f64>],
}

/// Four values of `buf` from `3 i`.
#[inline(always)]
fn slot4(buf: &[f64], i: usize) -> [f64; 4] {
    buf[3 * i..3 * i + 4].try_into().expect("slot in range")
}

impl BlockOp for Gather<'_> {
    type Output = ();

    #[inline(always)]
    fn run<L: Lanes>(self, l: L) {
        let m = self.elements;
        let nt4 = 4 * m.tets.len();
        for (k, fo) in self.forces.iter_mut().enumerate() {
            let n = self.first + k;
            let slots = m.slots.of(n);
            let (ts, hs) = slots.split_at(m.slots.tets[n] as usize);
            let (mut even, mut odd) = (l.splat(0.0), l.splat(0.0));
            let mut pairs = ts.chunks_exact(2);
            for p in &mut pairs {
                even = l.add(even, l.load(slot4(self.tslots, p[0] as usize)));
                odd = l.add(odd, l.load(slot4(self.tslots, p[1] as usize)));
            }
            if let [s] = pairs.remainder() {
                even = l.add(even, l.load(slot4(self.tslots, *s as usize)));
            }
            let mut pairs = hs.chunks_exact(2);
            for p in &mut pairs {
                even = l.add(even, l.load(slot4(self.hslots, p[0] as usize - nt4)));
                odd = l.add(odd, l.load(slot4(self.hslots, p[1] as usize - nt4)));
            }
            if let [s] = pairs.remainder() {
                even = l.add(even, l.load(slot4(self.hslots, *s as usize - nt4)));
            }
            let v = l.store(l.add(even, odd));
            *fo = Vector3::new(v[0], v[1], v[2]);
        }
    }
}
