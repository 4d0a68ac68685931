//! Regressions for the steps that were quadratic in the number of input polygons (issue 8):
//! each runs on an input large enough that the quadratic version would time the suite out,
//! and checks what the step must preserve.

use radiosity::generate::{furnished_room, tessellated};
use radiosity::mesh::merge::merge_coplanar;
use radiosity::mesh::split_at_contacts;
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::solve::{SolveOptions, SolverKind};

/// A floor under 20,000 boxes: 80,000 contact segments in one polygon. Cutting each piece by
/// every segment took 1.6 s for 1,000 boxes and grew as the square (about 10 minutes here);
/// divided first, it is O(s log s). The pieces must tile every surface exactly.
#[test]
fn a_floor_under_twenty_thousand_boxes_splits_in_linear_time() {
    let room = furnished_room(20_000, 3);
    let pieces = split_at_contacts(&room);
    let mut area = vec![0.0; room.surfaces.len()];
    for (s, p) in &pieces {
        area[*s] += p.area();
    }
    for (s, a) in room.surfaces.iter().zip(&area) {
        // Clipping moves vertices by rounding only: 1e-9 of the area.
        let want = s.polygon.area();
        assert!(
            (a - want).abs() <= 1e-9 * want,
            "{}: {a} of {want} m²",
            s.object
        );
    }
    // Each box footprint adds a few pieces and each division one: linear in the input.
    assert!(
        pieces.len() < 4 * room.surfaces.len(),
        "{} pieces",
        pieces.len()
    );
    // Every box stands on the floor: its 4 bottom edges cut it, so the floor has pieces
    // under boxes (at least one per box).
    let floor = room
        .surfaces
        .iter()
        .position(|s| s.object == "floor")
        .unwrap();
    let floor_pieces = pieces.iter().filter(|(s, _)| *s == floor).count();
    assert!(floor_pieces > 20_000, "{floor_pieces} floor pieces");
}

/// Object names of 50,000 objects (a linear scan per name was 10⁹ string comparisons).
#[test]
fn fifty_thousand_object_names_in_linear_time() {
    let room = furnished_room(50_000, 5);
    let names = room.object_names();
    // Furniture, floor, ceiling, four walls and the luminaires (one emitting panel each),
    // each named once.
    let panels = room
        .surfaces
        .iter()
        .filter(|s| room.material(s).is_emitter())
        .count();
    assert_eq!(names.len(), 50_000 + 6 + panels);
}

/// A Cornell box of 380,000 triangles merges back into its 20 polygons, and the hierarchical
/// solve of a 60,000-triangle one is the plain box's: same leaves, same links, the same
/// radiosity per object. The hierarchy, not the input, sets the cost.
#[test]
fn a_tessellated_cornell_box_costs_what_the_box_costs() {
    let plain = radiosity::cornell::cornell_box();
    let (merged, _) = merge_coplanar(&tessellated(&plain, 100));
    assert_eq!(merged.surfaces.len(), plain.surfaces.len());

    let settings = SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::Hierarchical,
            ..Default::default()
        },
        ..Default::default()
    };
    let a = solve_scene(&plain, &settings, &NoProgress).unwrap();
    let fine = tessellated(&plain, 40);
    assert_eq!(fine.surfaces.len(), 38 * 40 * 40);
    let b = solve_scene(&fine, &settings, &NoProgress).unwrap();
    assert_eq!(a.mesh.elements.len(), b.mesh.elements.len());
    let per_object = |s: &radiosity::Solved| {
        let mut sum = vec![[0.0; 3]; s.mesh.objects.len()];
        let mut area = vec![0.0; s.mesh.objects.len()];
        for (e, r) in s.mesh.elements.iter().zip(&s.solution.radiosity) {
            let o = s.mesh.surfaces[e.surface as usize].object as usize;
            for c in 0..3 {
                sum[o][c] += r[c] * e.area;
            }
            area[o] += e.area;
        }
        sum.iter()
            .zip(&area)
            .map(|(s, a)| s.map(|x| x / a))
            .collect::<Vec<_>>()
    };
    let (pa, pb) = (per_object(&a), per_object(&b));
    assert_eq!(a.mesh.objects, b.mesh.objects);
    for ((name, x), y) in a.mesh.objects.iter().zip(&pa).zip(&pb) {
        for c in 0..3 {
            // The merged outlines equal the originals to rounding, so the solutions agree
            // to rounding amplified by the iteration (1e-9 relative).
            assert!(
                (x[c] - y[c]).abs() <= 1e-9 * x[c].abs().max(1e-12),
                "{name}: {x:?} vs {y:?}"
            );
        }
    }
}
