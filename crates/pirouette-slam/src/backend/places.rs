//! The place index a stream's revisits are looked up in, for every
//! sensor: each node's 360° view (a camera sweep's profile, a laser
//! keyframe's view of the scans about it) filed as a place with the node
//! it belongs to. A camera map asks it whether a sweep is a place seen
//! before; a laser log asks it where the estimate may be lost.

use pirouette_places::{PlaceIndex, PlaceMeta, PlacesError, Signature, SignatureConfig, StoredProfile};
use pirouette_profile::Rop;

/// A place index over a stream's nodes.
pub(crate) struct Places {
    index: PlaceIndex,
    dataset: u32,
    /// The node of each place.
    node_of_place: Vec<usize>,
}

impl Places {
    /// No places yet; `name` names the stream in the index.
    pub fn new(name: &str) -> Result<Self, PlacesError> {
        let mut index = PlaceIndex::new(SignatureConfig::default())?;
        let dataset = index.dataset_id(name);
        Ok(Self {
            index,
            dataset,
            node_of_place: Vec::new(),
        })
    }

    /// The signature of a 360° view; `None` where it saw too little of
    /// the circle to be a place.
    pub fn signature(&self, view: &Rop) -> Result<Option<Signature>, PlacesError> {
        match self.index.transforms().signature(view) {
            Ok(s) => Ok(Some(s)),
            Err(PlacesError::IncompleteSweep { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Files `signature`, of `view`, as the place of node `node` (`id` its
    /// name in the index), with the view's profile where `keep_profile`
    /// (a metric refinement of a match reads it).
    pub fn file(
        &mut self,
        node: usize,
        id: u32,
        signature: &Signature,
        view: &Rop,
        keep_profile: bool,
    ) -> Result<(), PlacesError> {
        let meta = PlaceMeta {
            dataset: self.dataset,
            sweep: id,
            truth: None,
            profile: keep_profile.then(|| StoredProfile::from_rop(view)),
            map_pose: None,
            look_alike: None,
        };
        self.index.insert(signature, view.max_range_m, meta)?;
        self.node_of_place.push(node);
        Ok(())
    }

    /// The node of place `place` (an index of a query's answer).
    pub fn node(&self, place: usize) -> usize {
        self.node_of_place[place]
    }

    /// The index, to be queried.
    pub fn index(&self) -> &PlaceIndex {
        &self.index
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_places::QueryConfig;
    use std::f64::consts::{PI, TAU};

    /// A room's view from three spots, filed as nodes 4, 9 and 20: the
    /// view from the second again is answered with node 9; a view that
    /// saw a quarter of the circle is no place.
    #[test]
    fn a_view_filed_is_found_again_as_its_node() {
        let view_from = |x: f64, y: f64, seen: f64| {
            let mut rop = Rop::empty(-PI, TAU / 360.0, 360, 8.0);
            for b in 0..360 {
                let a = -PI + (b as f64 + 0.5) * TAU / 360.0;
                if a + PI > seen {
                    continue;
                }
                // The walls of a 6 m × 4 m room about the origin.
                let (c, s) = (a.cos(), a.sin());
                let tx = if c > 0.0 { (3.0 - x) / c } else { (-3.0 - x) / c };
                let ty = if s > 0.0 { (2.0 - y) / s } else { (-2.0 - y) / s };
                rop.insert(a, tx.min(ty) as f32, None);
            }
            rop
        };
        let mut places = Places::new("run").unwrap();
        for (node, (x, y)) in [(4, (-1.5, 0.5)), (9, (0.5, -0.8)), (20, (2.0, 1.0))] {
            let view = view_from(x, y, TAU);
            let sig = places.signature(&view).unwrap().expect("a whole circle");
            places.file(node, node as u32, &sig, &view, true).unwrap();
        }
        let again = places.signature(&view_from(0.5, -0.8, TAU)).unwrap().unwrap();
        let best = &places.index().query(&again, &QueryConfig::default())[0];
        assert_eq!(places.node(best.place), 9);
        assert!(places
            .signature(&view_from(0.0, 0.0, PI / 2.0))
            .unwrap()
            .is_none());
    }
}
