// Temporary experiment: does a preconditioner built on the deformed geometry cut GMRES?
use bs_dr::WarmStart;
use bs_scene::Prepared;
use bs_scene::compose::compose;
use bs_scene::solve::{SolveSettings, prepare_solver, solve_composed_from};

#[test]
#[ignore]
fn exp_deformed() {
    let p20 = Prepared::load(std::path::Path::new("/tmp/sA.toml")).unwrap();
    let p21 = Prepared::load(std::path::Path::new("/tmp/sB.toml")).unwrap();
    let s = SolveSettings::of(&p20);
    let mut c20 = compose(&p20).unwrap();
    let (sol, _) = solve_composed_from(&mut c20, &s, None, &mut |_| {}).unwrap();
    println!("cold 20: {} newton {} gmres", sol.report.steps, sol.report.linear_iterations);
    let u = sol.displacements.clone();
    // Warm 20 -> 21 with K0.
    let mut c21 = compose(&p21).unwrap();
    prepare_solver(&mut c21, &s).unwrap();
    let prep0 = c21.preparation.take().unwrap();
    // Preconditioner on the deformed geometry.
    let mut pd = p21.clone();
    for (x, d) in pd.mesh.nodes.iter_mut().zip(&u) {
        *x += d;
    }
    let mut cd = compose(&pd).unwrap();
    let t = std::time::Instant::now();
    prepare_solver(&mut cd, &s).unwrap();
    println!("deformed preparation {:?}", t.elapsed());
    let prepd = cd.preparation.take().unwrap();
    for (name, prep) in [("K0", prep0), ("deformed", prepd)] {
        let mut c = compose(&p21).unwrap();
        c.preparation = Some(prep);
        let t = std::time::Instant::now();
        let (sol, _) = solve_composed_from(
            &mut c,
            &s,
            Some(WarmStart { state: &u, secant: None }),
            &mut |_| {},
        )
        .unwrap();
        println!(
            "{name}: warm 21: {} newton {} gmres {:?}",
            sol.report.steps,
            sol.report.linear_iterations,
            t.elapsed()
        );
        // and cold 21 for reference
        let t = std::time::Instant::now();
        let (sol, _) = solve_composed_from(&mut c, &s, None, &mut |_| {}).unwrap();
        println!(
            "{name}: cold 21: {} newton {} gmres {:?}",
            sol.report.steps,
            sol.report.linear_iterations,
            t.elapsed()
        );
    }
}
