//! ROS `map_server` maps: a trinary P5 PGM and its YAML.

use crate::{OccupancyGrid, FREE_THRESH, OCCUPIED_THRESH};

/// Grey level of an occupied cell.
pub const OCCUPIED: u8 = 0;
/// Grey level of a free cell.
pub const FREE: u8 = 254;
/// Grey level of an unknown cell.
pub const UNKNOWN: u8 = 205;

/// Unknown cells kept around the known part of an exported map.
pub const MAP_BORDER_CELLS: i64 = 10;

/// A map as `map_server` reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct RosMap {
    /// Image width, cells.
    pub width: usize,
    /// Image height, cells.
    pub height: usize,
    /// Grey levels, row-major, first row at the top (largest y).
    pub pixels: Vec<u8>,
    /// Cell side, metres.
    pub resolution_m: f64,
    /// Map-frame position of the bottom-left corner of the image, metres.
    pub origin_m: [f64; 2],
    /// Probability above which a cell is occupied.
    pub occupied_thresh: f64,
    /// Probability below which a cell is free.
    pub free_thresh: f64,
}

impl RosMap {
    /// The trinary map of `grid` with `map_server`'s default thresholds
    /// (occupied above 0.65, free below 0.196), cropped to the cells any
    /// profile touched plus a border of [`MAP_BORDER_CELLS`].
    pub fn from_grid(grid: &OccupancyGrid) -> Self {
        let (occupied_thresh, free_thresh) = (OCCUPIED_THRESH, FREE_THRESH);
        let (min_i, min_j, width, height) = match grid.known_extent() {
            Some((lo, hi)) => {
                let b = MAP_BORDER_CELLS;
                (
                    lo.0 - b,
                    lo.1 - b,
                    (hi.0 - lo.0 + 1 + 2 * b) as usize,
                    (hi.1 - lo.1 + 1 + 2 * b) as usize,
                )
            }
            None => (0, 0, 0, 0),
        };
        let mut pixels = vec![UNKNOWN; width * height];
        for row in 0..height {
            let j = min_j + (height - 1 - row) as i64;
            for col in 0..width {
                let p = grid.probability(min_i + col as i64, j);
                pixels[row * width + col] = if p > occupied_thresh {
                    OCCUPIED
                } else if p < free_thresh {
                    FREE
                } else {
                    UNKNOWN
                };
            }
        }
        let s = grid.resolution_m();
        Self {
            width,
            height,
            pixels,
            resolution_m: s,
            origin_m: [min_i as f64 * s, min_j as f64 * s],
            occupied_thresh,
            free_thresh,
        }
    }

    /// The binary P5 PGM file.
    pub fn pgm(&self) -> Vec<u8> {
        let mut out = format!("P5\n{} {}\n255\n", self.width, self.height).into_bytes();
        out.extend_from_slice(&self.pixels);
        out
    }

    /// The YAML file, naming the PGM as `image`.
    pub fn yaml(&self, image: &str) -> String {
        format!(
            "image: {image}\nmode: trinary\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: {}\nfree_thresh: {}\n",
            self.resolution_m, self.origin_m[0], self.origin_m[1], self.occupied_thresh, self.free_thresh
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridConfig;
    use pirouette_geom::Pose2;
    use pirouette_profile::Rop;

    #[test]
    fn trinary_image_puts_the_obstacle_where_the_yaml_says() {
        let mut rop = Rop::covering(-0.2, 0.2, 0.25f64.to_radians(), 0.9).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 0.5);
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        // Five looks: a floor cell's probability falls to 0.12, below the
        // free threshold; the obstacle's rises to 0.99.
        for _ in 0..5 {
            g.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        }
        let m = RosMap::from_grid(&g);
        assert!(m.pixels.iter().all(|p| [OCCUPIED, FREE, UNKNOWN].contains(p)));
        // The pixel of map point (0.505, 0.0): column from x, row from the top.
        let col = ((0.505 - m.origin_m[0]) / m.resolution_m).floor() as usize;
        let row = m.height - 1 - ((0.0 - m.origin_m[1]) / m.resolution_m).floor() as usize;
        assert_eq!(m.pixels[row * m.width + col], OCCUPIED);
        let col_free = ((0.3 - m.origin_m[0]) / m.resolution_m).floor() as usize;
        assert_eq!(m.pixels[row * m.width + col_free], FREE);
        // Cropped to what was seen, with the border.
        assert!(m.width <= 60 + 2 * MAP_BORDER_CELLS as usize, "{}", m.width);
        let pgm = m.pgm();
        assert!(pgm.starts_with(format!("P5\n{} {}\n255\n", m.width, m.height).as_bytes()));
        assert_eq!(
            pgm.len(),
            m.width * m.height + format!("P5\n{} {}\n255\n", m.width, m.height).len()
        );
        let yaml = m.yaml("map.pgm");
        assert!(
            yaml.contains("image: map.pgm")
                && yaml.contains("negate: 0")
                && yaml.contains("resolution: 0.01")
        );
    }
}
