//! The encodings of the command-level values that cross ranks: mesh pieces gathered for welding and
//! slice fits broadcast by their owners. Built on [`crate::par::Wire`], so the format is the one
//! every other message uses.

use crate::contour::planes::SliceSummary;
use crate::contour::SectionFit;
use crate::mesh::clean::Indexing;
use crate::mesh::MeshPiece;
use crate::par::{Reader, Wire};
use crate::spline::{Carrier, Kernel, Normalisation, Spline};

impl Wire for MeshPiece {
    fn put(&self, out: &mut Vec<u8>) {
        self.edge_ids.put(out);
        self.positions.put(out);
        self.triangles.put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let edge_ids = Wire::take(r);
        let positions = Wire::take(r);
        MeshPiece { edge_ids, positions, triangles: Wire::take(r) }
    }
}

/// A kernel travels as (dim, order) and, for a compactly supported one, its name and support.
impl Wire for Kernel {
    fn put(&self, out: &mut Vec<u8>) {
        (self.dim(), self.order()).put(out);
        self.wendland_part().map(|w| (w.kind.name().to_string(), w.support)).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let (dim, order) = Wire::take(r);
        let compact: Option<(String, f64)> = Wire::take(r);
        match compact {
            None => Kernel::new(dim, order),
            Some((name, support)) => Kernel::wendland(&name, support),
        }
        .expect("a kernel sent by another rank is valid")
    }
}

impl Wire for Spline {
    fn put(&self, out: &mut Vec<u8>) {
        self.kernel.put(out);
        self.centres.put(out);
        self.weights.put(out);
        self.poly.put(out);
        (self.norm.centre, self.norm.scale).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let kernel = Wire::take(r);
        let centres = Wire::take(r);
        let weights = Wire::take(r);
        let poly = Wire::take(r);
        let (centre, scale) = Wire::take(r);
        Spline { kernel, centres, weights, poly, norm: Normalisation { centre, scale } }
    }
}

/// A section carrier travels as its specification (exact: floats print their shortest round-trip
/// form).
impl Wire for SectionFit {
    fn put(&self, out: &mut Vec<u8>) {
        self.carrier.to_string().put(out);
        self.spline.put(out);
        (self.points, self.merged).put(out);
        (self.residual, self.max_abs_at_points).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let spec = String::take(r);
        let carrier = Carrier::parse(&spec, 2).expect("a carrier sent by another rank parses");
        let spline = Wire::take(r);
        let (points, merged) = Wire::take(r);
        let (residual, max_abs_at_points) = Wire::take(r);
        SectionFit { carrier, spline, points, merged, residual, max_abs_at_points }
    }
}

impl Wire for SliceSummary {
    fn put(&self, out: &mut Vec<u8>) {
        [
            self.planes,
            self.slices,
            self.contours,
            self.points,
            self.joined,
            self.merged,
            self.crossings,
            self.flat,
            self.gaps,
            self.first_gap,
            self.indexing.joined_vertices,
            self.indexing.repeated_faces,
            self.indexing.collapsed_faces,
        ]
        .put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let [planes, slices, contours, points, joined, merged, crossings, flat, gaps, first_gap, joined_vertices, repeated_faces, collapsed_faces] =
            Wire::take(r);
        let indexing = Indexing { joined_vertices, repeated_faces, collapsed_faces };
        SliceSummary {
            planes,
            slices,
            contours,
            points,
            joined,
            merged,
            crossings,
            flat,
            gaps,
            first_gap,
            indexing,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mesh_pieces_and_section_fits_round_trip() {
        let p = MeshPiece {
            edge_ids: vec![3, 99],
            positions: vec![[0.1, 0.2, 0.3], [1.0, -2.0, 3e-300]],
            triangles: vec![[0, 1, 1]],
        };
        assert_eq!(MeshPiece::decode(&p.encode()), p);
        let kernel = Kernel::new(2, 2).unwrap();
        let fit = SectionFit {
            carrier: Carrier::parse("ball:0.125,-3,0.1", 2).unwrap(),
            spline: Spline {
                kernel,
                centres: vec![0.1, 0.2, 0.3, 0.4],
                weights: vec![1.0 / 3.0, -2.0],
                poly: vec![0.5, 0.25, 1e-17],
                norm: Normalisation { centre: [0.5, 1.5, 0.0], scale: 2.0 / 7.0 },
            },
            points: 2,
            merged: 1,
            residual: 1e-15,
            max_abs_at_points: 0.0,
        };
        let back = SectionFit::decode(&fit.encode());
        assert_eq!(back.carrier.to_string(), fit.carrier.to_string());
        assert_eq!(back.spline.weights, fit.spline.weights);
        assert_eq!(back.spline.norm.scale, fit.spline.norm.scale);
        assert_eq!(back.spline.poly, fit.spline.poly);
        assert_eq!((back.points, back.merged), (2, 1));
        let w = Kernel::wendland("wendland4", 0.25).unwrap();
        assert_eq!(Kernel::decode(&w.encode()), w);
        assert_eq!(Kernel::decode(&kernel.encode()), kernel);
    }
}
