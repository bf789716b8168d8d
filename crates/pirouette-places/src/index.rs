//! The place index: keys in a k-d tree, candidates re-ranked by a shift
//! search on the DCT-compressed profiles, colour as evidence.

use crate::signature::{colour_distance, ColourSectors, Signature, SignatureConfig, Transforms, KEY_DIMS};
use crate::stored::StoredProfile;
use crate::PlacesError;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use serde::{Deserialize, Serialize};
use std::num::NonZero;

/// Where a place came from, and what refines a match to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaceMeta {
    /// Index of its dataset's name in [`IndexContents::datasets`].
    pub dataset: u32,
    /// The sweep's id in its dataset.
    pub sweep: u32,
    /// The true pose of the sweep's first frame `(x, y, θ)` (metres,
    /// radians) where its dataset has ground truth: for evaluation only,
    /// never read by a query.
    pub truth: Option<[f64; 3]>,
    /// The sweep's profile, kept for metric refinement of a match.
    pub profile: Option<StoredProfile>,
    /// The sweep's first frame in its dataset's map `(x, y, θ)` (metres,
    /// radians), where the index was built from a mapped run: two
    /// matches to places of one dataset agree when they put the query
    /// at one pose of that map.
    pub map_pose: Option<[f64; 3]>,
    /// Where else in its dataset's map the place's view fits about as
    /// well, in the place's own frame `(x, y, θ)` (metres, radians): a
    /// query matched to the place may stand there instead.
    pub look_alike: Option<[f64; 3]>,
}

/// Everything an index holds, as saved: the signatures in flat arrays
/// (one entry per place, in insertion order) and each place's
/// [`PlaceMeta`].
///
/// # Memory
/// Per place, [`SignatureConfig::signature_bytes`] (180 with the
/// defaults), the metadata, and the stored profile where kept (2
/// bytes per bin).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IndexContents {
    /// How the signatures were made.
    pub config: SignatureConfig,
    /// The soft range limit of every place's sweep, metres (`None` while
    /// empty).
    pub limit_m: Option<f32>,
    /// Names of the datasets the places came from.
    pub datasets: Vec<String>,
    /// Rotation-invariant keys.
    pub keys: Vec<[f32; KEY_DIMS]>,
    /// DCT coefficients, K per place.
    pub dct: Vec<f32>,
    /// Colour sectors seen, one mask per place.
    pub colour_seen: Vec<u32>,
    /// Colour tags, `sectors` per place.
    pub colour: Vec<[u8; 2]>,
    /// Where each place came from.
    pub meta: Vec<PlaceMeta>,
}

/// Settings of a query.
#[derive(Debug, Clone, PartialEq)]
pub struct QueryConfig {
    /// Places taken from the key search to be re-ranked.
    pub neighbours: usize,
    /// Rotations tried per place: the deepest minima of the shift search
    /// (a view from a spot a decimetre away can line up best a few tens
    /// of degrees off, where a near wall's shape changes most).
    pub rotations: usize,
    /// Candidates whose colour tags differ more than this (the mean
    /// log-chromaticity difference of [`crate::colour_distance`] over the
    /// sectors both saw) are dropped.
    pub max_colour_distance: f32,
    /// The fewest colour sectors both must have tagged for colour to count.
    pub min_shared_sectors: usize,
}

impl Default for QueryConfig {
    /// 16 neighbours, 4 rotations each; colour differing by more than 0.5 in
    /// log-chromaticity (a tenth of a channel's share differs by about
    /// 0.1; red against white by 2 or more) over at least 4 shared
    /// sectors rejects.
    fn default() -> Self {
        Self {
            neighbours: 16,
            rotations: 4,
            max_colour_distance: 0.5,
            min_shared_sectors: 4,
        }
    }
}

/// A stored place a query may be, ranked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The place's index.
    pub place: usize,
    /// The query's heading relative to the place's first frame, radians,
    /// from the shift search.
    pub rotation_rad: f64,
    /// RMS difference of the rebuilt profiles at that rotation, metres.
    pub profile_rms_m: f32,
    /// Distance between the keys, metres.
    pub key_distance_m: f32,
    /// Colour difference at that rotation, where enough sectors are shared.
    pub colour_distance: Option<f32>,
}

/// The fewest places kept out of the tree before it is rebuilt.
const REBUILD_MIN: usize = 256;

/// The tree is rebuilt when the places kept out of it outnumber this
/// fraction of it: a scan of those costs each query, a rebuild costs
/// each insert (about this many re-filings of a place in all).
const REBUILD_FRACTION: usize = 16;

/// The leading key dimensions the k-d tree is built on. The key's
/// dimensions come in falling order of spread (the mean range, then the
/// amplitudes of ever shorter harmonics: on random rooms the first four
/// hold 93 % of the variance), so a tree on these four prunes well where
/// one on all twelve degenerates to a scan, and the distance over them
/// is a lower bound of the full one.
pub const TREE_DIMS: usize = 4;

/// How many places the first, prefix-only pass of a key search fetches
/// to bound the full distance of the `k`-th nearest (a speed setting:
/// the search is exact at any value).
const PREFIX_FETCH: usize = 128;

/// A key search scans every key instead of the tree where it expects
/// more than this fraction of the places within `τ` on the prefix.
const SCAN_FRACTION: usize = 8;

/// A place index. Places are inserted one at a time; the k-d tree holds
/// all but the most recent, which a query scans directly, and is rebuilt
/// when those outnumber a sixteenth of it (so the tree grows by
/// sixteenths, and a place is re-filed about seventeen times in all).
pub struct PlaceIndex {
    contents: IndexContents,
    transforms: Transforms,
    tree: Option<ImmutableKdTree<f32, u32, TREE_DIMS, 32>>,
    in_tree: usize,
}

impl std::fmt::Debug for PlaceIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlaceIndex")
            .field("places", &self.len())
            .field("config", &self.contents.config)
            .finish()
    }
}

impl PlaceIndex {
    /// An empty index.
    pub fn new(config: SignatureConfig) -> Result<Self, PlacesError> {
        let transforms = Transforms::new(&config)?;
        Ok(Self {
            contents: IndexContents {
                config,
                limit_m: None,
                datasets: Vec::new(),
                keys: Vec::new(),
                dct: Vec::new(),
                colour_seen: Vec::new(),
                colour: Vec::new(),
                meta: Vec::new(),
            },
            transforms,
            tree: None,
            in_tree: 0,
        })
    }

    /// An index of saved contents, checked for consistency.
    pub fn from_contents(contents: IndexContents) -> Result<Self, PlacesError> {
        let transforms = Transforms::new(&contents.config)?;
        let n = contents.keys.len();
        let c = &contents.config;
        let bad = |problem: &str| {
            Err(PlacesError::BadIndex {
                problem: problem.into(),
            })
        };
        if contents.dct.len() != n * c.coefficients
            || contents.colour_seen.len() != n
            || contents.colour.len() != n * c.sectors
            || contents.meta.len() != n
        {
            return bad("its arrays do not hold one entry per place");
        }
        if contents
            .meta
            .iter()
            .any(|m| m.dataset as usize >= contents.datasets.len())
        {
            return bad("a place names a dataset the index does not list");
        }
        if n > 0 && !contents.limit_m.is_some_and(|l| l.is_finite() && l > 0.0) {
            return bad("no soft range limit");
        }
        if contents
            .keys
            .iter()
            .flatten()
            .chain(&contents.dct)
            .any(|v| !v.is_finite())
        {
            return bad("a signature holds a value that is not finite");
        }
        let mut index = Self {
            contents,
            transforms,
            tree: None,
            in_tree: 0,
        };
        index.rebuild();
        Ok(index)
    }

    /// What the index holds, as saved.
    pub fn contents(&self) -> &IndexContents {
        &self.contents
    }

    /// The transforms of its signature settings.
    pub fn transforms(&self) -> &Transforms {
        &self.transforms
    }

    /// Places held.
    pub fn len(&self) -> usize {
        self.contents.keys.len()
    }

    /// Whether it holds no place.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The index of a dataset name, added if new.
    pub fn dataset_id(&mut self, name: &str) -> u32 {
        let names = &mut self.contents.datasets;
        match names.iter().position(|n| n == name) {
            Some(i) => i as u32,
            None => {
                names.push(name.to_owned());
                (names.len() - 1) as u32
            }
        }
    }

    /// Adds a place; returns its index. Its signature must have been made
    /// with the index's settings and the same soft range limit as the
    /// places before it.
    pub fn insert(
        &mut self,
        signature: &Signature,
        limit_m: f32,
        meta: PlaceMeta,
    ) -> Result<usize, PlacesError> {
        self.check_signature(signature, limit_m)?;
        if meta.dataset as usize >= self.contents.datasets.len() {
            return Err(PlacesError::BadIndex {
                problem: format!("dataset {} is not listed", meta.dataset),
            });
        }
        let c = &mut self.contents;
        c.limit_m = Some(limit_m);
        c.keys.push(signature.key);
        c.dct.extend_from_slice(&signature.dct);
        c.colour_seen.push(signature.colour.seen);
        c.colour.extend_from_slice(&signature.colour.chroma);
        c.meta.push(meta);
        let pending = self.len() - self.in_tree;
        if pending > REBUILD_MIN.max(self.in_tree / REBUILD_FRACTION) {
            self.rebuild();
        }
        Ok(self.len() - 1)
    }

    /// Whether a query's signature can be compared with the places.
    pub fn check_signature(&self, signature: &Signature, limit_m: f32) -> Result<(), PlacesError> {
        let c = &self.contents.config;
        if signature.dct.len() != c.coefficients || signature.colour.chroma.len() != c.sectors {
            return Err(PlacesError::Mismatch {
                problem: format!(
                    "signature of {} coefficients and {} sectors, index of {} and {}",
                    signature.dct.len(),
                    signature.colour.chroma.len(),
                    c.coefficients,
                    c.sectors
                ),
            });
        }
        if signature.key.iter().chain(&signature.dct).any(|v| !v.is_finite()) {
            return Err(PlacesError::BadProfile {
                problem: "signature holds a value that is not finite".into(),
            });
        }
        match self.contents.limit_m {
            Some(l) if l != limit_m => Err(PlacesError::Mismatch {
                problem: format!("soft range limit {limit_m} m, the index's places {l} m"),
            }),
            _ => Ok(()),
        }
    }

    /// Place `i`'s signature.
    ///
    /// # Panics
    /// When `i` is not a place.
    pub fn signature(&self, i: usize) -> Signature {
        let c = &self.contents;
        let (k, s) = (c.config.coefficients, c.config.sectors);
        Signature {
            key: c.keys[i],
            dct: c.dct[i * k..(i + 1) * k].to_vec(),
            colour: ColourSectors {
                seen: c.colour_seen[i],
                chroma: c.colour[i * s..(i + 1) * s].to_vec(),
            },
        }
    }

    fn rebuild(&mut self) {
        self.in_tree = self.len();
        self.tree = (self.in_tree > 0).then(|| {
            let prefixes: Vec<[f32; TREE_DIMS]> = self.contents.keys.iter().map(prefix).collect();
            ImmutableKdTree::new_from_slice(&prefixes)
        });
    }

    /// The `k` places nearest a key (squared distances), nearest first:
    /// from the tree and the places not yet in it. Exact, in two passes
    /// over the tree of [`TREE_DIMS`]-dimensional key prefixes: the
    /// prefixes nearest the query's give the full distance `τ` that the
    /// `k`-th nearest place is within; every place whose prefix lies
    /// within `τ` is then measured on the full key (no other can be
    /// nearer, since the prefix distance never exceeds the full one).
    pub fn nearest_keys(&self, key: &[f32; KEY_DIMS], k: usize) -> Vec<(usize, f32)> {
        let keys = &self.contents.keys;
        let full = |item: u32| (item as usize, squared_distance(key, &keys[item as usize]));
        let mut found: Vec<(usize, f32)> = match (&self.tree, NonZero::new(PREFIX_FETCH.max(k))) {
            (Some(tree), Some(fetch)) if k > 0 => {
                let q = prefix(key);
                let near = tree.nearest_n::<SquaredEuclidean>(&q, fetch);
                let reach = near.last().map_or(0.0, |n| n.distance);
                let mut first: Vec<(usize, f32)> = near.into_iter().map(|n| full(n.item)).collect();
                sort_nearest(&mut first, k);
                let tau = first.last().map_or(f32::INFINITY, |f| f.1);
                // Every place within τ on the prefix was fetched already.
                if first.len() == self.in_tree || reach > tau {
                    return keep_nearest(first, k, self.pending(key));
                }
                // Places within τ on the prefix, by the density of the
                // fetched ones (a 4-D ball holds ∝ r⁴ = (r²)²): where that
                // is a large part of the tree, a scan is cheaper.
                let expected = fetch.get() as f32 * (tau / reach.max(f32::MIN_POSITIVE)).powi(2);
                if expected > (self.in_tree / SCAN_FRACTION) as f32 {
                    let all = keys[..self.in_tree].iter().enumerate();
                    keep_nearest(
                        Vec::new(),
                        k,
                        all.map(|(i, other)| (i, squared_distance(key, other))),
                    )
                } else {
                    tree.within_unsorted::<SquaredEuclidean>(&q, tau)
                        .into_iter()
                        .map(|n| full(n.item))
                        .collect()
                }
            }
            _ => Vec::new(),
        };
        sort_nearest(&mut found, k);
        keep_nearest(found, k, self.pending(key))
    }

    /// The places not yet in the tree, with their squared key distances.
    fn pending<'a>(&'a self, key: &'a [f32; KEY_DIMS]) -> impl Iterator<Item = (usize, f32)> + 'a {
        let keys = &self.contents.keys;
        (self.in_tree..self.len()).map(move |i| (i, squared_distance(key, &keys[i])))
    }

    /// The `k` places nearest a key by a scan of every key: the reference
    /// for [`PlaceIndex::nearest_keys`].
    pub fn nearest_keys_brute(&self, key: &[f32; KEY_DIMS], k: usize) -> Vec<(usize, f32)> {
        let all = self.contents.keys.iter().enumerate();
        keep_nearest(
            Vec::new(),
            k,
            all.map(|(i, other)| (i, squared_distance(key, other))),
        )
    }

    /// The places a query may be, and at which rotation, best first: the
    /// key search's [`QueryConfig::neighbours`] nearest, each lined up
    /// with the query by a shift search on the rebuilt profiles (its
    /// [`QueryConfig::rotations`] best rotations), those whose colours
    /// disagree at that rotation dropped, ranked by the RMS difference of
    /// the profiles. A place may appear once per rotation.
    pub fn query(&self, query: &Signature, config: &QueryConfig) -> Vec<Candidate> {
        let near = self.nearest_keys(&query.key, config.neighbours);
        self.rerank(query, &near, config)
    }

    /// [`PlaceIndex::query`] with the key search by a scan of every key.
    pub fn query_brute(&self, query: &Signature, config: &QueryConfig) -> Vec<Candidate> {
        let near = self.nearest_keys_brute(&query.key, config.neighbours);
        self.rerank(query, &near, config)
    }

    fn rerank(&self, query: &Signature, near: &[(usize, f32)], config: &QueryConfig) -> Vec<Candidate> {
        let t = &self.transforms;
        let k = self.contents.config.coefficients;
        let mut q = Vec::new();
        t.rebuild(&query.dct, &mut q);
        let q_spec = t.spectrum(&q);
        let mut stored = Vec::new();
        let s = self.contents.config.sectors;
        let mut out: Vec<Candidate> = Vec::with_capacity(near.len() * config.rotations);
        for &(place, d2) in near {
            t.rebuild(&self.contents.dct[place * k..(place + 1) * k], &mut stored);
            for (rotation_rad, profile_rms_m) in t.best_shifts(&q, &q_spec, &stored, config.rotations) {
                let colour_distance = colour_distance(
                    &query.colour,
                    self.contents.colour_seen[place],
                    &self.contents.colour[place * s..(place + 1) * s],
                    rotation_rad,
                    config.min_shared_sectors,
                );
                if colour_distance.is_some_and(|c| c > config.max_colour_distance) {
                    continue;
                }
                out.push(Candidate {
                    place,
                    rotation_rad,
                    profile_rms_m,
                    key_distance_m: d2.sqrt(),
                    colour_distance,
                });
            }
        }
        out.sort_by(|a, b| {
            a.profile_rms_m
                .total_cmp(&b.profile_rms_m)
                .then(a.place.cmp(&b.place))
                .then(a.rotation_rad.total_cmp(&b.rotation_rad))
        });
        out
    }
}

/// The leading [`TREE_DIMS`] dimensions of a key.
fn prefix(key: &[f32; KEY_DIMS]) -> [f32; TREE_DIMS] {
    std::array::from_fn(|d| key[d])
}

fn squared_distance(a: &[f32; KEY_DIMS], b: &[f32; KEY_DIMS]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The `k` nearest of `found` (sorted, at most `k`) and `more`, sorted,
/// without holding or sorting all of `more`.
fn keep_nearest(
    mut found: Vec<(usize, f32)>,
    k: usize,
    more: impl Iterator<Item = (usize, f32)>,
) -> Vec<(usize, f32)> {
    let mut worst = match found.len() < k {
        true => f32::INFINITY,
        false => found.last().map_or(f32::INFINITY, |f| f.1),
    };
    for (i, d) in more {
        if found.len() < k || d <= worst {
            found.push((i, d));
            if found.len() > 2 * k.max(8) {
                sort_nearest(&mut found, k);
                worst = found.last().map_or(f32::INFINITY, |f| f.1);
            }
        }
    }
    sort_nearest(&mut found, k);
    found
}

/// Sorts by distance (then place) and keeps the first `k`.
fn sort_nearest(found: &mut Vec<(usize, f32)>, k: usize) {
    found.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    found.truncate(k);
}
