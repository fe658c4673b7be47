use super::*;

/// A flat square patch of m × m unit cells (2 triangles each) in z = 0, outward +z.
fn square(m: usize) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
    let mut p = Vec::new();
    for j in 0..=m {
        for i in 0..=m {
            p.push(Point3::new(i as f64, j as f64, 0.0));
        }
    }
    let mut t = Vec::new();
    let row = m + 1;
    for j in 0..m {
        for i in 0..m {
            let a = j * row + i;
            t.push([a, a + 1, a + row + 1]);
            t.push([a, a + row + 1, a + row]);
        }
    }
    (p, t)
}

fn params(sigma: f64) -> SurfaceParams {
    SurfaceParams { sigma, stiffness: 2.0, max_distance: 3.0 }
}

/// A noisy scan of the plane z = 0.5 over the half x > 5 of a 10 × 10 patch, with a tenth
/// of gross outliers: quadrature points well inside the scanned half are pulled onto
/// z = 0.5 (within the plane fit's share of the noise), those of the other half not at all,
/// and each spring's stiffness is κ times a third of its face's area (½) times its
/// coverage.
#[test]
fn covered_nodes_are_pulled_onto_the_scanned_plane_and_the_rest_stay_free() {
    let (x, faces) = square(10);
    let mut rng = bs_mesh::rng::SplitMix64::new(11);
    let mut points: Vec<Point3<f64>> = (0..1500)
        .map(|_| Point3::new(rng.range(5.0, 10.0), rng.range(0.0, 10.0), 0.5 + 0.1 * rng.normal()))
        .collect();
    for p in points.iter_mut().step_by(10) {
        p.z += 2.0 * rng.range(-1.0, 1.0).signum();
    }
    let mut fit = SurfaceFit::new(points, &faces, &x, params(0.1));
    let mut springs = Springs::new();
    fit.linearise(&x, &mut springs);
    // The radius: four times the point spacing (0.18 for 1500 points on 5 × 10).
    let r = fit.radius();
    assert!((0.7..1.0).contains(&r), "{r}");
    let point_of = |s: &Spring| {
        Point3::from((0..3).map(|k| x[s.nodes[k]].coords * s.weights[k]).sum::<Vector3<f64>>())
    };
    let zero = vec![Vector3::zeros(); x.len()];
    for s in springs.terms() {
        let q = point_of(s);
        assert!(q.x > 5.0 - 0.45 * r, "{q} is pulled");
        let m = 1.5 * r;
        if q.x > 5.0 + m && q.x < 10.0 - m && q.y > m && q.y < 10.0 - m {
            // Inside: the residual is the point's height below 0.5, within the noise's share.
            let res = s.residual(&x, &zero);
            assert!((res + 0.5).abs() < 0.05, "{q}: {res}");
            // Full coverage but for the noise of the points' centroid across the line (about
            // 0.1 R with 40 points in the cylinder; the taper starts at 0.2 R): within 10 %.
            let k = s.stiffness / (2.0 / 6.0);
            assert!(k <= 1.0 + 1e-12 && k > 0.9, "{q}: {k}");
        }
    }
    // The faces of the scanned half (100 of 200) have three springs each, less those at its
    // edges that fade out.
    assert!((240..=330).contains(&springs.len()), "{} springs", springs.len());
    // Classified against the patch lifted onto the plane: the inliers within the noise,
    // the outliers rejected.
    let lifted: Vec<Point3<f64>> = x.iter().map(|p| p + Vector3::new(0.0, 0.0, 0.5)).collect();
    fit.classify(&lifted);
    let f = fit.fits();
    let outliers = f.iter().filter(|p| p.status == PointStatus::Outlier).count();
    assert!(f.iter().step_by(10).all(|p| p.status == PointStatus::Outlier));
    assert!((150..170).contains(&outliers), "{outliers}");
    let median = {
        let mut r: Vec<f64> =
            f.iter().filter(|p| p.status == PointStatus::Inlier).map(|p| p.residual).collect();
        r.sort_by(f64::total_cmp);
        r[r.len() / 2]
    };
    assert!(median.abs() < 0.02 && (fit.scale() - 0.1).abs() < 0.03, "{median} {}", fit.scale());
}

/// Points beyond the patch's edge and points far away are told apart from inliers.
#[test]
fn border_and_far_points_are_classified_apart() {
    let (x, faces) = square(4);
    let points = vec![
        Point3::new(2.0, 2.0, 0.1),
        Point3::new(5.5, 2.0, 0.0),
        Point3::new(2.0, 2.0, 9.0),
        Point3::new(1.0, 3.0, -0.1),
    ];
    let mut fit = SurfaceFit::new(points, &faces, &x, params(0.2));
    fit.classify(&x);
    let s: Vec<_> = fit.fits().iter().map(|f| f.status).collect();
    assert_eq!(
        s,
        [PointStatus::Inlier, PointStatus::Border, PointStatus::Far, PointStatus::Inlier]
    );
    assert!((fit.fits()[0].residual - 0.1).abs() < 1e-12);
    assert!((fit.fits()[3].residual + 0.1).abs() < 1e-12);
}

#[test]
fn the_border_of_a_square_is_its_outline() {
    let (_, faces) = square(2);
    let tris: Vec<[u32; 3]> = faces.iter().map(|f| f.map(|a| a as u32)).collect();
    let border = border_edges(&tris);
    assert_eq!(border.len(), 8);
    assert!(border.iter().all(|e| !e.contains(&4))); // the centre is inside
}

#[test]
fn the_stiffness_rule_scales_with_area_and_noise() {
    assert_eq!(surface_stiffness(1000.0, 1.0, 900.0, 1.0), 30_000.0);
    assert_eq!(surface_stiffness(1000.0, 2.0, 900.0, 1.0), 7_500.0);
    // Capped at 100 μ/h.
    assert_eq!(surface_stiffness(1000.0, 0.1, 900.0, 5.0), 20_000.0);
}

/// A patch scanned beyond its edges by an exact grid: every quadrature point is fully
/// covered (its spring carries κ times a third of its face's area), whatever its place.
#[test]
fn a_patch_scanned_beyond_its_edges_is_covered_everywhere() {
    let (x, faces) = square(4);
    let mut points = Vec::new();
    for j in 0..=80 {
        for i in 0..=80 {
            points.push(Point3::new(-2.0 + 0.1 * i as f64, -2.0 + 0.1 * j as f64, 0.3));
        }
    }
    let mut fit = SurfaceFit::new(points, &faces, &x, params(0.01));
    let mut springs = Springs::new();
    fit.linearise(&x, &mut springs);
    assert_eq!(springs.len(), 3 * faces.len());
    for s in springs.terms() {
        assert!((s.stiffness - 2.0 / 6.0).abs() < 1e-12, "{:?}", s);
    }
}
