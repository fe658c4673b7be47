//! The blocked (structure-of-arrays) copies of the elements that the SIMD kernels read:
//! tets (hexes) `4b … 4b+3` form block `b`, one element per lane. Derived in `Model::new`
//! from `Model::tets` and `Model::hexes`, which stay the reference (array-of-structures)
//! data for every other reader. The last block is padded with inert lanes (zero gradients,
//! volume and hourglass matrix, the nodes of lane 0: `F = I`, zero force, and a T4ANP `J̄`
//! that is lane 0's), whose slots no node gathers: a padded lane never reports an inversion
//! of its own.

use bs_material::{Elastic, Material};

use crate::element::{Hex, Solid, Tet};

/// Elements per block (f64 lanes of a 256-bit vector).
pub(crate) const LANES: usize = 4;

/// How a block evaluates its stress.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum BlockLaw {
    /// Every real lane is Neo-Hookean with these parameters: the vectorised law.
    NeoHookean(Elastic),
    /// Any other law or a mix of parameters: each lane through the scalar
    /// `Material::pk1_fj`.
    PerElement,
}

/// Four tetrahedra, lane `l` = tet `4b + l`.
#[derive(Debug, Clone)]
pub(crate) struct TetBlock {
    /// Reference gradients of nodes 1, 2, 3: `g[3(a − 1) + k][l] = ∂N_a/∂X_k` of lane `l`
    /// (`g_0 = −(g_1 + g_2 + g_3)` exactly, as `Model::new` computes it, so it is not kept).
    pub g: [[f64; LANES]; 9],
    /// Reference volumes.
    pub vol: [f64; LANES],
    /// Node indices: `nodes[a][l]`.
    pub nodes: [[u32; LANES]; 4],
    /// T4ANP averaging groups of the corners: `anp[a][l]` (see `Tet::anp`).
    pub anp: [[u32; LANES]; 4],
    /// The block's stress evaluation.
    pub law: BlockLaw,
}

/// Four hexahedra, lane `l` = hex `4b + l`.
#[derive(Debug, Clone)]
pub(crate) struct HexBlock {
    /// Mean gradients: `g[3a + k][l]` of lane `l`.
    pub g: [[f64; LANES]; 24],
    /// Hourglass matrices (symmetric), upper triangle row by row (see `h8::sym_index`).
    pub hg: [[f64; LANES]; 36],
    /// Reference volumes.
    pub vol: [f64; LANES],
    /// Node indices: `nodes[a][l]`.
    pub nodes: [[u32; LANES]; 8],
    /// The block's stress evaluation.
    pub law: BlockLaw,
}

/// The law of a run of elements with materials `mats`.
fn block_law(mats: impl Iterator<Item = u32> + Clone, solids: &[Solid]) -> BlockLaw {
    let law = |m: u32| match solids[m as usize].material {
        Material::NeoHookean(e) => Some(e),
        _ => None,
    };
    let first = mats.clone().next().and_then(law);
    match first {
        Some(e) if mats.map(law).all(|l| l == Some(e)) => BlockLaw::NeoHookean(e),
        _ => BlockLaw::PerElement,
    }
}

/// Builds the blocks of `hexes` (materials from `solids`).
pub(crate) fn hex_blocks(hexes: &[Hex], solids: &[Solid]) -> Vec<HexBlock> {
    hexes
        .chunks(LANES)
        .map(|chunk| {
            let mut b = HexBlock {
                g: [[0.0; LANES]; 24],
                hg: [[0.0; LANES]; 36],
                vol: [0.0; LANES],
                nodes: [[0; LANES]; 8],
                law: block_law(chunk.iter().map(|h| h.mat), solids),
            };
            for (l, h) in chunk.iter().enumerate() {
                for a in 0..8 {
                    b.nodes[a][l] = h.nodes[a];
                    for k in 0..3 {
                        b.g[3 * a + k][l] = h.g[a][k];
                    }
                    for c in a..8 {
                        b.hg[sym_index(a, c)][l] = h.hg[a][c];
                    }
                }
                b.vol[l] = h.vol;
            }
            for l in chunk.len()..LANES {
                for a in 0..8 {
                    b.nodes[a][l] = b.nodes[a][0];
                }
            }
            b
        })
        .collect()
}

/// Builds the blocks of `tets` (materials from `solids`).
pub(crate) fn tet_blocks(tets: &[Tet], solids: &[Solid]) -> Vec<TetBlock> {
    tets.chunks(LANES)
        .map(|chunk| {
            let mut b = TetBlock {
                g: [[0.0; LANES]; 9],
                vol: [0.0; LANES],
                nodes: [[0; LANES]; 4],
                anp: [[0; LANES]; 4],
                law: BlockLaw::PerElement,
            };
            for (l, t) in chunk.iter().enumerate() {
                for a in 0..4 {
                    b.nodes[a][l] = t.nodes[a];
                    b.anp[a][l] = t.anp[a];
                }
                for a in 1..4 {
                    for k in 0..3 {
                        b.g[3 * (a - 1) + k][l] = t.g[a][k];
                    }
                }
                b.vol[l] = t.vol;
            }
            for l in chunk.len()..LANES {
                for a in 0..4 {
                    b.nodes[a][l] = b.nodes[a][0];
                    b.anp[a][l] = b.anp[a][0];
                }
            }
            b.law = block_law(chunk.iter().map(|t| t.mat), solids);
            b
        })
        .collect()
}

/// Index of entry `(a, c)` of a symmetric 8×8 matrix stored as its upper triangle, row by
/// row (36 entries).
#[inline(always)]
pub(crate) const fn sym_index(a: usize, c: usize) -> usize {
    let (r, s) = if a <= c { (a, c) } else { (c, a) };
    r * 8 - r * (r + 1) / 2 + s
}
