//! A disjoint-set forest over indices (union-find with path halving): a tube's regions,
//! the strokes' spanning tree.

/// An index into the forest: `u32` (the meshes' and trees' indices) or `usize`.
pub(crate) trait Node: Copy + PartialEq {
    /// As a slice index.
    fn at(self) -> usize;
}

impl Node for u32 {
    fn at(self) -> usize {
        self as usize
    }
}

impl Node for usize {
    fn at(self) -> usize {
        self
    }
}

/// The root of `i`'s set in the forest `parent` (a root is its own parent), halving
/// the path on the way.
pub(crate) fn root<T: Node>(parent: &mut [T], mut i: T) -> T {
    while parent[i.at()] != i {
        parent[i.at()] = parent[parent[i.at()].at()];
        i = parent[i.at()];
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_follow_the_links_and_paths_shorten() {
        // 3 -> 2 -> 1 -> 0, and 4 alone.
        let mut parent: Vec<u32> = vec![0, 0, 1, 2, 4];
        assert_eq!(root(&mut parent, 3), 0);
        assert_eq!(root(&mut parent, 4), 4);
        // Halving linked 3 to its grandparent.
        assert_eq!(parent[3], 1);
        let mut p: Vec<usize> = vec![1, 1];
        assert_eq!(root(&mut p, 0), 1);
    }
}
