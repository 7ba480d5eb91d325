//! `cta uncertainty`: the Ch IV budget (eq 26) and the angle uncertainty it causes (eq 40).

use crate::args::{announce_plot, check_diameter};
use anyhow::{anyhow, Result};
use clap::Args;
use cta_lab::budget::Budget;
use cta_lab::uncertainty::UncertaintyTable;
use serde_json::json;
use std::path::{Path, PathBuf};

/// Ch IV: the CTA uncertainty budget (eq 26) and the 2-D angle uncertainty it implies (eq 40).
#[derive(Debug, Args)]
pub struct UncertaintyArgs {
    /// Budget file (TOML, `[[item]]` tables with `name` and mils `x`, `y`, `z` or
    /// `x_plus`/`x_minus`...); default: thesis Table 2.
    #[arg(long)]
    pub budget: Option<PathBuf>,
    /// Sensor diameter D in inches, to compare with the Ch II near-field error.
    #[arg(long = "diameter-in", default_value_t = 0.35)]
    pub diameter_in: f64,
    /// Draw Figure 40 (CTA angle uncertainty vs near-field error) to this SVG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// The budget file given (`--budget`), or thesis Table 2, with its unit caution on stderr.
pub fn load_budget(path: Option<&Path>) -> Result<Budget> {
    let budget = Budget::load_or_table2(path)?;
    if let (Some(w), Some(p)) = (&budget.unit_warning, &budget.file) {
        crate::say::warning(format_args!("{}: {w}", p.display()));
    }
    Ok(budget)
}

/// Run `cta uncertainty`.
pub fn run(a: &UncertaintyArgs) -> Result<()> {
    check_diameter(a.diameter_in)?;
    if let Some(p) = &a.plot {
        cta_lab::plot::check_plot_path(p)?;
    }
    let budget = load_budget(a.budget.as_deref())?;
    let table = UncertaintyTable::new(budget, a.diameter_in);
    if a.json {
        let inputs: Vec<&std::path::Path> = a.budget.iter().map(|p| p.as_path()).collect();
        println!(
            "{}",
            crate::json_with_provenance(&to_json(&table), &inputs)?
        );
    } else {
        print_table(&table);
    }
    if let Some(p) = &a.plot {
        table
            .plot(p)
            .map_err(|e| anyhow!("{e}; the table above is complete, the plot was not written"))?;
        announce_plot(p);
    }
    Ok(())
}

fn to_json(t: &UncertaintyTable) -> serde_json::Value {
    let r = t.rss_mils;
    json!({
        "items": t.budget.items.iter().map(|(n, m)| json!({"name": n, "mils": m})).collect::<Vec<_>>(),
        "rss_mils": {"x": r[0].max(r[1]), "y": r[2].max(r[3]), "z": r[4].max(r[5]),
                      "x_plus": r[0], "x_minus": r[1], "y_plus": r[2], "y_minus": r[3], "z_plus": r[4], "z_minus": r[5]},
        "eq40_u_theta_times_R_deg_in": t.rows.iter().map(|r| json!({"theta_deg": r.theta_deg, "value": r.u_theta_times_r})).collect::<Vec<_>>(),
        "nearfield_over_cta": t.rows.iter().map(|r| json!({"theta_deg": r.theta_deg, "lambertian": r.lambertian, "quartic": r.quartic})).collect::<Vec<_>>(),
        "uy_in": t.rss_in[1],
    })
}

fn print_table(t: &UncertaintyTable) {
    let r = t.rss_mils;
    println!("CTA uncertainty budget (thesis Ch IV, eq 26), mils:");
    println!(
        "{:<36} {:>6} {:>6} {:>6} {:>6} {:>6} {:>6}",
        "item", "X+", "X-", "Y+", "Y-", "Z+", "Z-"
    );
    for (n, m) in &t.budget.items {
        println!(
            "{:<36} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}",
            n, m[0], m[1], m[2], m[3], m[4], m[5]
        );
    }
    println!(
        "{:<36} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2}",
        "root-sum-square", r[0], r[1], r[2], r[3], r[4], r[5]
    );
    if t.budget.file.is_none() {
        println!(
            "(Table 2 rounds the text's 21.25 mil plate offset to 21.3: with it X is 31.54, Y 24.41, printed 31.5, 24.4; 21.25 is used here)"
        );
    }
    println!(
        "Angle uncertainty in 2-D (eq 40), u_theta x R, and the near-field error over it (D = {} in):",
        t.diameter_in
    );
    for row in &t.rows {
        println!(
            "  theta {:>4} deg: {:.3} deg in; near-field / CTA = {:.1} (Lambertian), {:.1} (printed quartic)",
            row.theta_deg, row.u_theta_times_r, row.lambertian, row.quartic
        );
    }
    println!("Note: the 3-D angle uncertainty (eq 36), which `cta evaluate` gives per separation, does not use the");
    println!("thesis's sensitivities (eqs 34/35: singular at x = y = z) but the corrected |d theta/d x| =");
    println!("sqrt(y^2+z^2)/|b|^2 (README, thesis inconsistency 4), about 1.4x larger.");
}
