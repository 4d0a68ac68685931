//! A node's links, each stored in the 32-bit words its kind needs.
//!
//! As one enum every [`Link`] takes 40 bytes, the size of the largest transfer. But two
//! thirds of a furnished room's links are uniform transfers, one coefficient each (room of
//! 10,000 objects: 9.4 M of 14.4 M), and most of the rest polygon transfers of seven. Here
//! a link is its first word, the source node with the transfer's kind in the top
//! [`KIND_BITS`] bits, its error coefficient δ, and the transfer's numbers as they are:
//!
//! | kind | words | bytes |
//! |---|---|---|
//! | uniform | 3 | 12 |
//! | polygon with neither gradient nor moment | 3 | 12 |
//! | from or to a cluster | 6 | 24 |
//! | polygon, tensor | 9 | 36 |
//!
//! The numbers are kept as their bits, so a link reads back exactly as it was stored. A
//! polygon transfer whose gradient and moment are all +0 (the oracle stores them so between
//! polygons that never split: [`super::Hierarchical::polygon_polygon`]) is kept as its mean
//! alone, and reads back with them +0.

use super::{Link, Transfer};

/// Bits of a link's first word that hold its kind; the others hold the source node.
const KIND_BITS: u32 = 3;
/// Where the kind starts in the first word.
const KIND_SHIFT: u32 = 32 - KIND_BITS;
/// Node indices must stay below this to be stored as a link's source: the refinement
/// splits no node once the arena holds a fifth of this
/// ([`super::Hierarchical::refine_reporting`]; at the estimate's 1 kB a node, a fifth is
/// 100 GiB of nodes, past any memory limit the hierarchy runs under here).
pub(super) const MAX_NODES: usize = 1 << KIND_SHIFT;

const POLYGON: u32 = 0;
const UNIFORM: u32 = 1;
const FROM_CLUSTER: u32 = 2;
const TO_CLUSTER: u32 = 3;
const TENSOR: u32 = 4;
/// A polygon transfer with gradient and moment all +0 (see the module documentation).
const FLAT_POLYGON: u32 = 5;

/// The links into one node, in the order they were added (or by source once sorted).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkList {
    words: Vec<u32>,
}

/// Words a link of this transfer takes.
pub(super) fn words_of(transfer: &Transfer) -> usize {
    match transfer {
        Transfer::Uniform(_) => 3,
        t if flat(t) => 3,
        Transfer::FromCluster(..) | Transfer::ToCluster(..) => 6,
        Transfer::Polygon { .. } | Transfer::Tensor(..) => 9,
    }
}

/// Whether `transfer` is a polygon transfer with gradient and moment all +0 (their bits 0,
/// so that storing the mean alone loses nothing, not even a sign).
fn flat(transfer: &Transfer) -> bool {
    match transfer {
        Transfer::Polygon {
            gradient, moment, ..
        } => gradient.iter().chain(moment).all(|v| v.to_bits() == 0),
        _ => false,
    }
}

impl LinkList {
    /// Appends `link`.
    pub fn push(&mut self, link: &Link) {
        debug_assert!((link.source as usize) < MAX_NODES);
        let head = |kind: u32| link.source | (kind << KIND_SHIFT);
        let bits = |x: &[f32]| {
            x.iter()
                .map(|v| v.to_bits())
                .collect::<smallvec::SmallVec<[u32; 7]>>()
        };
        let delta = link.delta.to_bits();
        match link.transfer {
            Transfer::Polygon { f, .. } if flat(&link.transfer) => {
                self.words.extend([head(FLAT_POLYGON), delta, f.to_bits()]);
            }
            Transfer::Polygon {
                f,
                gradient,
                moment,
            } => {
                self.words.extend([head(POLYGON), delta, f.to_bits()]);
                self.words.extend(bits(&gradient));
                self.words.extend(bits(&moment));
            }
            Transfer::Uniform(c) => self.words.extend([head(UNIFORM), delta, c.to_bits()]),
            Transfer::FromCluster(g, m) | Transfer::ToCluster(g, m) => {
                let kind = if matches!(link.transfer, Transfer::FromCluster(..)) {
                    FROM_CLUSTER
                } else {
                    TO_CLUSTER
                };
                self.words.extend([head(kind), delta]);
                self.words.extend(bits(&g));
                self.words.push(m.to_bits());
            }
            Transfer::Tensor(t, m) => {
                self.words.extend([head(TENSOR), delta]);
                self.words.extend(bits(&t));
                self.words.push(m.to_bits());
            }
        }
    }

    /// Appends `run`, growing the storage by at least a quarter when it is full (doubled,
    /// the lists held 1.44 times their links in the room of 3000 objects).
    pub fn extend_growing(&mut self, run: impl IntoIterator<Item = Link>) {
        for link in run {
            let need = words_of(&link.transfer);
            if self.words.capacity() - self.words.len() < need {
                self.words
                    .reserve_exact(need.max(self.words.len() / 4).max(4 * 9));
            }
            self.push(&link);
        }
    }

    /// Gives back the storage beyond the links held (a list grows by a quarter at a time,
    /// [`LinkList::extend_growing`]).
    pub fn shrink_to_fit(&mut self) {
        self.words.shrink_to_fit();
    }

    /// The links, decoded.
    pub fn iter(&self) -> Iter<'_> {
        Iter { words: &self.words }
    }

    /// Number of links (counted: a walk over the words).
    pub fn len(&self) -> usize {
        self.iter().count()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }

    /// Words held (4 bytes each).
    pub fn words(&self) -> usize {
        self.words.len()
    }

    /// Keeps the links for which `keep` is true, in order, in place.
    pub fn retain(&mut self, mut keep: impl FnMut(&Link) -> bool) {
        let (mut read, mut write) = (0, 0);
        while read < self.words.len() {
            let (link, n) = decode(&self.words[read..]);
            if keep(&link) {
                self.words.copy_within(read..read + n, write);
                write += n;
            }
            read += n;
        }
        self.words.truncate(write);
    }

    /// Orders the links by source node, keeping the order of links from one source (a
    /// stable sort).
    pub fn sort_by_source(&mut self) {
        // Most lists are sorted already: checked without decoding them into a vector.
        if self.iter().map(|l| l.source).is_sorted() {
            return;
        }
        let mut links: Vec<Link> = self.iter().collect();
        links.sort_by_key(|l| l.source);
        self.words.clear();
        for link in &links {
            self.push(link);
        }
    }
}

impl<'a> IntoIterator for &'a LinkList {
    type Item = Link;
    type IntoIter = Iter<'a>;
    fn into_iter(self) -> Iter<'a> {
        self.iter()
    }
}

/// The links of a [`LinkList`], decoded one after the other.
pub struct Iter<'a> {
    words: &'a [u32],
}

impl Iterator for Iter<'_> {
    type Item = Link;
    fn next(&mut self) -> Option<Link> {
        if self.words.is_empty() {
            return None;
        }
        let (link, n) = decode(self.words);
        self.words = &self.words[n..];
        Some(link)
    }
}

/// The link at the start of `w`, and how many words it takes. (Each kind's words are taken
/// as one array: one bounds check per link.)
#[inline]
fn decode(w: &[u32]) -> (Link, usize) {
    let f = f32::from_bits;
    let three = |a: &[u32]| [f(a[0]), f(a[1]), f(a[2])];
    let source = w[0] & ((1 << KIND_SHIFT) - 1);
    match w[0] >> KIND_SHIFT {
        UNIFORM => {
            let a: &[u32; 3] = w[..3].try_into().expect("a uniform link is three words");
            let link = Link {
                source,
                transfer: Transfer::Uniform(f(a[2])),
                delta: f(a[1]),
            };
            (link, 3)
        }
        FLAT_POLYGON => {
            let a: &[u32; 3] = w[..3]
                .try_into()
                .expect("a flat polygon link is three words");
            let link = Link {
                source,
                transfer: Transfer::Polygon {
                    f: f(a[2]),
                    gradient: [0.0; 3],
                    moment: [0.0; 3],
                },
                delta: f(a[1]),
            };
            (link, 3)
        }
        kind @ (FROM_CLUSTER | TO_CLUSTER) => {
            let a: &[u32; 6] = w[..6].try_into().expect("a cluster link is six words");
            let (g, m) = (three(&a[2..5]), f(a[5]));
            let transfer = if kind == FROM_CLUSTER {
                Transfer::FromCluster(g, m)
            } else {
                Transfer::ToCluster(g, m)
            };
            let link = Link {
                source,
                transfer,
                delta: f(a[1]),
            };
            (link, 6)
        }
        kind => {
            let a: &[u32; 9] = w[..9]
                .try_into()
                .expect("a polygon or tensor link is nine words");
            let transfer = if kind == POLYGON {
                Transfer::Polygon {
                    f: f(a[2]),
                    gradient: three(&a[3..6]),
                    moment: three(&a[6..9]),
                }
            } else {
                Transfer::Tensor(
                    [f(a[2]), f(a[3]), f(a[4]), f(a[5]), f(a[6]), f(a[7])],
                    f(a[8]),
                )
            };
            let link = Link {
                source,
                transfer,
                delta: f(a[1]),
            };
            (link, 9)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn every_kind() -> Vec<Link> {
        let f = |i: u32| i as f32 * 0.37 - 1.5;
        vec![
            Link {
                source: 7,
                transfer: Transfer::Polygon {
                    f: 0.25,
                    gradient: [f(1), f(2), -0.0],
                    moment: [f(4), f32::MIN_POSITIVE, f(6)],
                },
                delta: 0.125,
            },
            Link {
                source: 3,
                transfer: Transfer::Uniform(1e-30),
                delta: 2.5,
            },
            Link {
                source: (MAX_NODES - 1) as u32,
                transfer: Transfer::FromCluster([f(7), f(8), f(9)], 0.5),
                delta: 0.0,
            },
            Link {
                source: 0,
                transfer: Transfer::ToCluster([f(10), f(11), f(12)], 0.75),
                delta: f32::MAX,
            },
            Link {
                source: 3,
                transfer: Transfer::Tensor([f(13), f(14), f(15), f(16), f(17), f(18)], f(19)),
                delta: 1e-3,
            },
            Link {
                source: 1,
                transfer: Transfer::Uniform(0.0),
                delta: 0.0,
            },
            Link {
                source: 9,
                transfer: Transfer::Polygon {
                    f: f(20),
                    gradient: [0.0; 3],
                    moment: [0.0; 3],
                },
                delta: 0.5,
            },
            // A negative zero is a number of its own: nine words.
            Link {
                source: 10,
                transfer: Transfer::Polygon {
                    f: f(21),
                    gradient: [0.0, -0.0, 0.0],
                    moment: [0.0; 3],
                },
                delta: 0.5,
            },
        ]
    }

    /// Every kind of link reads back to the bit, in order, with the size of the table in
    /// the module's documentation.
    #[test]
    fn links_read_back_exactly() {
        let links = every_kind();
        let mut list = LinkList::default();
        list.extend_growing(links.iter().copied());
        let back: Vec<Link> = list.iter().collect();
        assert_eq!(back.len(), links.len());
        for (a, b) in back.iter().zip(&links) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
            assert_eq!(a.delta.to_bits(), b.delta.to_bits());
        }
        assert_eq!(list.len(), 8);
        assert_eq!(list.words(), 9 + 3 + 6 + 6 + 9 + 3 + 3 + 9);
        assert_eq!(
            list.words(),
            links.iter().map(|l| words_of(&l.transfer)).sum::<usize>()
        );
    }

    /// Retain keeps the chosen links in order; sorting by source is stable.
    #[test]
    fn retain_sort_and_shrink_keep_the_links_they_should() {
        let links = every_kind();
        let mut list = LinkList::default();
        list.extend_growing(links.iter().copied());
        list.retain(|l| !matches!(l.transfer, Transfer::ToCluster(..)));
        let kept: Vec<Link> = links
            .iter()
            .copied()
            .filter(|l| !matches!(l.transfer, Transfer::ToCluster(..)))
            .collect();
        assert_eq!(list.iter().collect::<Vec<_>>(), kept);
        list.sort_by_source();
        let mut sorted = kept.clone();
        sorted.sort_by_key(|l| l.source);
        assert_eq!(list.iter().collect::<Vec<_>>(), sorted);
        // The two links from node 3 keep their order: uniform, then tensor.
        let from3: Vec<Link> = list.iter().filter(|l| l.source == 3).collect();
        assert!(matches!(from3[0].transfer, Transfer::Uniform(_)));
        assert!(matches!(from3[1].transfer, Transfer::Tensor(..)));
        // Shrunk to fit, it holds the same links.
        let before: Vec<Link> = list.iter().collect();
        list.shrink_to_fit();
        assert_eq!(list.iter().collect::<Vec<_>>(), before);
        list.retain(|_| false);
        assert!(list.is_empty());
        assert_eq!(list.len(), 0);
    }
}
