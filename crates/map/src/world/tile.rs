//! One square of the world lattice: the fused signed distance, its weight, the
//! occupancy evidence and the raw votes of every sample, in flat arrays.

use super::Key;

/// A tile's samples, row after row (`local = (j - j0) * side + (i - i0)`).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Tile {
    /// Fused signed distance to the scans' curves, positive on the free side.
    pub sdf: Vec<f32>,
    /// How many scans' curves passed within the truncation of the sample (capped).
    pub weight: Vec<u16>,
    /// Occupancy log-odds, clamped (OctoMap's rule).
    pub occ: Vec<f32>,
    /// Scans whose beam returned at the sample.
    pub hits: Vec<u16>,
    /// Scans whose beam went past the sample.
    pub through: Vec<u16>,
    /// The last scan that voted at the sample, so a scan votes once.
    pub stamp: Vec<u32>,
    /// The weight behind `sdf`: each scan's share, by its heading error at the sample's
    /// range (`MapParams::heading_noise`), summed and capped like `weight`.
    pub evidence: Vec<f32>,
    /// The last scan that touched the tile (least recently seen tiles leave memory).
    pub seen: u64,
}

impl Tile {
    pub fn new(side: usize) -> Tile {
        let n = side * side;
        Tile {
            sdf: vec![0.0; n],
            weight: vec![0; n],
            occ: vec![0.0; n],
            hits: vec![0; n],
            through: vec![0; n],
            stamp: vec![u32::MAX; n],
            evidence: vec![0.0; n],
            seen: 0,
        }
    }

    /// Bytes a tile of `side` samples a side holds.
    pub fn bytes(side: usize) -> usize {
        side * side * (4 + 2 + 4 + 4 + 2 + 2 + 4) + std::mem::size_of::<Tile>()
    }

    /// The tile as bytes for a [`TileStore`](super::TileStore), little-endian.
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.sdf.len();
        let mut out = Vec::with_capacity(8 + n * 22);
        out.extend_from_slice(&self.seen.to_le_bytes());
        out.extend(self.sdf.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.weight.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.evidence.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.occ.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.hits.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.through.iter().flat_map(|v| v.to_le_bytes()));
        out.extend(self.stamp.iter().flat_map(|v| v.to_le_bytes()));
        out
    }

    /// The tile [`Tile::to_bytes`] wrote, or `None` when `bytes` is not one of `side`.
    pub fn from_bytes(bytes: &[u8], side: usize) -> Option<Tile> {
        let n = side * side;
        if bytes.len() != 8 + n * 22 {
            return None;
        }
        let (seen, mut rest) = bytes.split_at(8);
        let mut take = |k: usize| {
            let (a, b) = rest.split_at(k * n);
            rest = b;
            a
        };
        let f32s = |b: &[u8]| -> Vec<f32> {
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        };
        let u16s = |b: &[u8]| -> Vec<u16> {
            b.chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect()
        };
        let sdf = f32s(take(4));
        let weight = u16s(take(2));
        let evidence = f32s(take(4));
        let occ = f32s(take(4));
        let hits = u16s(take(2));
        let through = u16s(take(2));
        let stamp = take(4)
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let mut s = [0u8; 8];
        s.copy_from_slice(seen);
        Some(Tile {
            sdf,
            weight,
            occ,
            hits,
            through,
            stamp,
            evidence,
            seen: u64::from_le_bytes(s),
        })
    }
}

/// What the lattice knows at one sample, for the extraction and the scores.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Sample {
    pub sdf: f32,
    pub weight: u16,
    pub occ: f32,
    pub hits: u16,
    pub through: u16,
}

impl Tile {
    pub fn sample(&self, k: usize) -> Sample {
        Sample {
            sdf: self.sdf[k],
            weight: self.weight[k],
            occ: self.occ[k],
            hits: self.hits[k],
            through: self.through[k],
        }
    }
}

/// A tile's first row and first column, kept when the tile leaves memory: the cells
/// of its neighbours below and to the left end on them.
#[derive(Clone, Debug)]
pub(crate) struct Border {
    pub row: Vec<Sample>,
    pub column: Vec<Sample>,
}

impl Border {
    pub fn of(tile: &Tile, side: usize) -> Border {
        Border {
            row: (0..side).map(|i| tile.sample(i)).collect(),
            column: (0..side).map(|j| tile.sample(j * side)).collect(),
        }
    }
}

/// The tile holding sample `(i, j)` and the sample's index in it.
pub(crate) fn locate(i: i64, j: i64, side: usize) -> (Key, usize) {
    let s = side as i64;
    let (ti, tj) = (i.div_euclid(s), j.div_euclid(s));
    let (li, lj) = (i.rem_euclid(s), j.rem_euclid(s));
    ((ti, tj), (lj * s + li) as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tile_comes_back_from_its_bytes() {
        let mut t = Tile::new(4);
        t.sdf[3] = -0.25;
        t.weight[5] = 7;
        t.evidence[6] = 0.125;
        t.occ[15] = 3.5;
        t.hits[0] = 2;
        t.through[1] = 9;
        t.stamp[2] = 11;
        t.seen = 42;
        assert_eq!(Tile::from_bytes(&t.to_bytes(), 4), Some(t.clone()));
        assert_eq!(Tile::from_bytes(&t.to_bytes(), 5), None);
    }

    #[test]
    fn samples_on_either_side_of_zero_fall_in_their_tiles() {
        assert_eq!(locate(0, 0, 8), ((0, 0), 0));
        assert_eq!(locate(-1, 0, 8), ((-1, 0), 7));
        assert_eq!(locate(9, -9, 8), ((1, -2), 7 * 8 + 1));
    }
}
