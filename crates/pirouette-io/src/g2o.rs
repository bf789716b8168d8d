//! 2D pose graphs in g2o's text format: `VERTEX_SE2 id x y θ`,
//! `EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33` (the measurement of
//! pose `j` in pose `i`'s frame, then the upper triangle of its
//! information), `FIX id`, comments after `#`.

use crate::IoError;
use pirouette_geom::Pose2;
use pirouette_graph::{check_information, Edge, PoseGraph};
use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::path::Path;

/// A pose graph read from a g2o file, with the file's vertex ids.
#[derive(Debug, Clone, PartialEq)]
pub struct G2oGraph {
    /// The graph: node `k` is the vertex `ids[k]`; the held node is the
    /// `FIX`ed vertex, or the first.
    pub graph: PoseGraph,
    /// The g2o id of each node.
    pub ids: Vec<u64>,
    /// Whether the file gave the vertices' poses (`VERTEX_SE2` lines).
    /// Without them the nodes are the ids the edges name, in increasing
    /// order, at the origin until initialised.
    pub has_vertices: bool,
}

/// An edge as read: its line, the g2o ids it joins, its measurement and
/// information.
type RawEdge = (usize, u64, u64, Pose2, [[f64; 3]; 3]);

/// The most vertices or edges a file may hold: far beyond any real graph,
/// and refused before memory is spent on more.
pub const MAX_ELEMENTS: usize = 50_000_000;

/// Reads a g2o 2D pose graph, line by line.
///
/// # Errors
/// The file and line of: a line that is not `VERTEX_SE2`, `EDGE_SE2`,
/// `FIX`, blank or a comment; a wrong field count or a non-number; a
/// non-finite value; a vertex given twice; an edge to a vertex the file
/// does not give (when it gives vertices); an information matrix that is
/// not positive definite; an edge joining a vertex to itself.
pub fn read_g2o(path: &Path) -> Result<G2oGraph, IoError> {
    let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    parse_g2o(std::io::BufReader::new(file), path)
}

/// [`read_g2o`] from any reader; `path` names the source in errors.
pub fn parse_g2o(reader: impl BufRead, path: &Path) -> Result<G2oGraph, IoError> {
    let mut lines = Lines::default();
    for (n, line) in reader.lines().enumerate() {
        let line_no = n + 1;
        let line = line.map_err(|e| IoError::io(path, e))?;
        let bad = |problem: String| IoError::Line {
            path: path.to_path_buf(),
            line: line_no,
            problem,
        };
        let text = line.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            continue;
        }
        let mut fields = text.split_whitespace();
        let tag = fields.next().unwrap_or("");
        let rest: Vec<&str> = fields.collect();
        lines.take(line_no, tag, &rest, &bad)?;
    }
    lines.into_graph(path)
}

/// The lines of a g2o file read so far.
#[derive(Default)]
struct Lines {
    /// Each vertex's id and pose, in file order.
    vertices: Vec<(u64, Pose2)>,
    /// A vertex id's place in `vertices`.
    index: HashMap<u64, usize>,
    edges: Vec<RawEdge>,
    /// The `FIX` line's number and vertex.
    fixed: Option<(usize, u64)>,
}

impl Lines {
    /// Takes line `line_no`'s `tag` and fields; `bad` makes its errors.
    fn take(
        &mut self,
        line_no: usize,
        tag: &str,
        rest: &[&str],
        bad: &dyn Fn(String) -> IoError,
    ) -> Result<(), IoError> {
        let id = |s: &str| {
            s.parse::<u64>()
                .map_err(|_| bad(format!("`{s}` is not a vertex id")))
        };
        let number = |s: &str| -> Result<f64, IoError> {
            let v = s
                .parse::<f64>()
                .map_err(|_| bad(format!("`{s}` is not a number")))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(format!("`{s}` is not finite")))
            }
        };
        let count = |want: usize| {
            if rest.len() == want {
                Ok(())
            } else {
                Err(bad(format!(
                    "{tag} takes {want} fields, this line has {}",
                    rest.len()
                )))
            }
        };
        match tag {
            "VERTEX_SE2" => {
                count(4)?;
                let v = id(rest[0])?;
                let pose = Pose2::new(number(rest[1])?, number(rest[2])?, number(rest[3])?);
                if self.index.insert(v, self.vertices.len()).is_some() {
                    return Err(bad(format!("vertex {v} is given twice")));
                }
                if self.vertices.len() >= MAX_ELEMENTS {
                    return Err(bad(format!("more than {MAX_ELEMENTS} vertices")));
                }
                self.vertices.push((v, pose));
            }
            "EDGE_SE2" => {
                count(11)?;
                let (i, j) = (id(rest[0])?, id(rest[1])?);
                if i == j {
                    return Err(bad(format!("the edge joins vertex {i} to itself")));
                }
                let z = Pose2::new(number(rest[2])?, number(rest[3])?, number(rest[4])?);
                let u: Vec<f64> = rest[5..11].iter().map(|s| number(s)).collect::<Result<_, _>>()?;
                let info = [[u[0], u[1], u[2]], [u[1], u[3], u[4]], [u[2], u[4], u[5]]];
                check_information(&info).map_err(bad)?;
                if self.edges.len() >= MAX_ELEMENTS {
                    return Err(bad(format!("more than {MAX_ELEMENTS} edges")));
                }
                self.edges.push((line_no, i, j, z, info));
            }
            "FIX" => {
                count(1)?;
                self.fixed = Some((line_no, id(rest[0])?));
            }
            other => {
                return Err(bad(format!(
                    "`{other}` lines are not read (only VERTEX_SE2, EDGE_SE2 and FIX)"
                )))
            }
        }
        Ok(())
    }

    /// The graph the lines describe: where they give no vertices, the ids
    /// the edges name, in increasing order, at the origin.
    fn into_graph(mut self, path: &Path) -> Result<G2oGraph, IoError> {
        let has_vertices = !self.vertices.is_empty();
        if !has_vertices {
            let mut ids: Vec<u64> = self.edges.iter().flat_map(|e| [e.1, e.2]).collect();
            ids.sort_unstable();
            ids.dedup();
            for (k, &v) in ids.iter().enumerate() {
                self.index.insert(v, k);
                self.vertices.push((v, Pose2::IDENTITY));
            }
        }
        let index = &self.index;
        let node = |line: usize, v: u64| {
            index.get(&v).copied().ok_or_else(|| IoError::Line {
                path: path.to_path_buf(),
                line,
                problem: format!("vertex {v} is not given in the file (a dangling edge)"),
            })
        };
        let mut graph = PoseGraph::new(self.vertices.iter().map(|v| v.1).collect());
        for &(line, i, j, z, info) in &self.edges {
            graph
                .edges
                .push(Edge::new(node(line, i)?, node(line, j)?, z, info));
        }
        if let Some((line, v)) = self.fixed {
            graph.held = node(line, v)?;
        }
        if graph.poses.is_empty() {
            return Err(IoError::invalid(
                path,
                "no vertices and no edges: not a pose graph",
            ));
        }
        Ok(G2oGraph {
            graph,
            ids: self.vertices.iter().map(|v| v.0).collect(),
            has_vertices,
        })
    }
}

/// Writes a pose graph in g2o's format (every vertex, then every edge, with
/// `ids`' numbering), atomically.
pub fn write_g2o(path: &Path, g: &G2oGraph) -> Result<(), IoError> {
    write_pose_graph(path, &g.graph, &g.ids)
}

/// As [`write_g2o`], for a graph and its vertex ids held apart.
pub fn write_pose_graph(path: &Path, graph: &PoseGraph, ids: &[u64]) -> Result<(), IoError> {
    if ids.len() != graph.poses.len() {
        return Err(IoError::invalid(
            path,
            format!("{} vertex ids for {} poses", ids.len(), graph.poses.len()),
        ));
    }
    crate::atomic_write_with(path, |w| {
        for (id, p) in ids.iter().zip(&graph.poses) {
            writeln!(w, "VERTEX_SE2 {id} {} {} {}", p.x, p.y, p.theta)?;
        }
        for e in &graph.edges {
            let (z, o) = (e.measurement, e.information);
            let (Some(from), Some(to)) = (ids.get(e.from), ids.get(e.to)) else {
                return Err(std::io::Error::other(format!(
                    "an edge joins poses {} and {} of {}",
                    e.from,
                    e.to,
                    ids.len()
                )));
            };
            writeln!(
                w,
                "EDGE_SE2 {} {} {} {} {} {} {} {} {} {} {}",
                from, to, z.x, z.y, z.theta, o[0][0], o[0][1], o[0][2], o[1][1], o[1][2], o[2][2]
            )?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.g2o");
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    const EDGE_INFO: &str = "10 0 0 10 0 40";

    #[test]
    fn a_graph_with_ids_that_do_not_fit_is_not_written() {
        let (dir, path) = write(&format!(
            "VERTEX_SE2 5 0 0 0\nVERTEX_SE2 7 1 0.5 0.25\nEDGE_SE2 5 7 1 0.5 0.25 {EDGE_INFO}\n"
        ));
        let g = read_g2o(&path).unwrap();
        let out = dir.path().join("out.g2o");
        let e = write_pose_graph(&out, &g.graph, &[5]).unwrap_err();
        assert!(e.to_string().contains("out.g2o") && e.to_string().contains("1 vertex ids for 2 poses"));
        assert!(!out.exists());
        write_pose_graph(&out, &g.graph, &g.ids).unwrap();
        assert_eq!(read_g2o(&out).unwrap(), g);
    }

    #[test]
    fn reads_and_writes_back_the_same_graph() {
        let text = format!(
            "# a comment\nVERTEX_SE2 5 0 0 0\nVERTEX_SE2 7 1 0.5 0.25\n\nEDGE_SE2 5 7 1 0.5 0.25 {EDGE_INFO}\nFIX 7\n"
        );
        let (dir, path) = write(&text);
        let g = read_g2o(&path).unwrap();
        assert_eq!(g.ids, vec![5, 7]);
        assert!(g.has_vertices);
        assert_eq!(g.graph.held, 1);
        assert_eq!(g.graph.edges.len(), 1);
        assert_eq!(g.graph.edges[0].information[2][2], 40.0);
        let out = dir.path().join("out.g2o");
        write_g2o(&out, &g).unwrap();
        let again = read_g2o(&out).unwrap();
        assert_eq!(again.graph.poses, g.graph.poses);
        assert_eq!(again.graph.edges, g.graph.edges);
    }

    #[test]
    fn a_file_without_vertices_numbers_the_edges_ids() {
        let (_dir, path) = write(&format!(
            "EDGE_SE2 0 1 1 0 0 {EDGE_INFO}\nEDGE_SE2 1 2 1 0 0 {EDGE_INFO}\n"
        ));
        let g = read_g2o(&path).unwrap();
        assert!(!g.has_vertices);
        assert_eq!(g.ids, vec![0, 1, 2]);
        assert_eq!((g.graph.edges[1].from, g.graph.edges[1].to), (1, 2));
    }

    /// Each bad file is refused with its line named.
    #[test]
    fn bad_lines_are_refused_naming_the_line() {
        let cases = [
            ("VERTEX_SE2 0 0 0\n", 1, "takes 4 fields"),
            ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n", 2, "given twice"),
            ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 nan 0 0\n", 2, "not finite"),
            ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 x 0 0\n", 2, "not a number"),
            (
                "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 3 1 0 0 10 0 0 10 0 40\n",
                2,
                "dangling",
            ),
            ("EDGE_SE2 0 1 1 0 0 10 0 0 -10 0 40\n", 1, "positive definite"),
            ("EDGE_SE2 0 0 1 0 0 10 0 0 10 0 40\n", 1, "to itself"),
            ("EDGE_SE2 0 1 1 0 0 10 0 0 10 0 inf\n", 1, "not finite"),
            ("VERTEX_XY 0 0 0\n", 1, "not read"),
            ("VERTEX_SE2 -1 0 0 0\n", 1, "not a vertex id"),
        ];
        for (text, line, what) in cases {
            let (_dir, path) = write(text);
            let err = read_g2o(&path).unwrap_err();
            let msg = err.to_string();
            assert!(
                matches!(err, IoError::Line { line: l, .. } if l == line),
                "{text}: {msg}"
            );
            assert!(msg.contains(what) && msg.contains("g.g2o"), "{text}: {msg}");
        }
        let (_dir, path) = write("# nothing\n");
        assert!(read_g2o(&path)
            .unwrap_err()
            .to_string()
            .contains("not a pose graph"));
    }
}
