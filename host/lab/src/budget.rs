//! The CTA's apparatus uncertainty budget (thesis Ch IV): Table 2, or a lab's own budget file
//! of `[[item]]` tables in mils, whose root-sum-square (eq 26) bounds where a beacon is.

use cta_core::uncertainty::{self, Item};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Largest uncertainty of a budget item, mils: 1,000 in, far beyond any apparatus (the
/// root-sum-square of larger values can overflow to infinity).
pub const MAX_BUDGET_MILS: f64 = 1e6;

/// Why a budget file is refused; each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum BudgetError {
    /// The file could not be read.
    #[error("{}", .path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        error: std::io::Error,
    },
    /// Not TOML of `[[item]]` tables.
    #[error("{}: {error}", .path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// The TOML parser's message.
        error: String,
    },
    /// An item without any uncertainty.
    #[error(
        "{}: item `{item}` has no uncertainty: give mils as x, y, z (symmetric) or x_plus, x_minus, ...",
        .path.display()
    )]
    NoUncertainty {
        /// The file.
        path: PathBuf,
        /// The item's name.
        item: String,
    },
    /// An axis given both symmetric and by sides.
    #[error(
        "{}: item `{item}` gives both `{axis}` and `{axis}_plus`/`{axis}_minus`: give one (symmetric) or the sides",
        .path.display()
    )]
    BothForms {
        /// The file.
        path: PathBuf,
        /// The item's name.
        item: String,
        /// `x`, `y` or `z`.
        axis: &'static str,
    },
    /// A value outside 0..=[`MAX_BUDGET_MILS`].
    #[error(
        "{}: item `{item}`: uncertainty {} mils must be in 0..={MAX_BUDGET_MILS} (1,000 in)",
        .path.display(), mils_text(.value)
    )]
    OutOfRange {
        /// The file.
        path: PathBuf,
        /// The item's name.
        item: String,
        /// The value, mils.
        value: f64,
    },
    /// No items.
    #[error("{}: no [[item]] in the budget", .path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// Every value 0.
    #[error(
        "{}: every uncertainty in the budget is 0: there is no apparatus uncertainty to compare",
        .path.display()
    )]
    AllZero {
        /// The file.
        path: PathBuf,
    },
}

/// A value in mils for a message: in exponent form when huge.
fn mils_text(v: &f64) -> String {
    if v.abs() < 1e7 {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BudgetFile {
    item: Vec<BudgetItem>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BudgetItem {
    name: String,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    x_plus: Option<f64>,
    x_minus: Option<f64>,
    y_plus: Option<f64>,
    y_minus: Option<f64>,
    z_plus: Option<f64>,
    z_minus: Option<f64>,
}

/// An uncertainty budget: named items, each with its 1-sigma in mils along X+, X-, Y+, Y-, Z+,
/// Z- (Table 2's columns).
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// The items: name and mils.
    pub items: Vec<(String, [f64; 6])>,
    /// The file it was read from; `None` for Table 2.
    pub file: Option<PathBuf>,
    /// A caution when the values look like inches rather than mils (without `warning: ` and
    /// the file's name).
    pub unit_warning: Option<String>,
}

impl Budget {
    /// Thesis Table 2.
    pub fn table2() -> Budget {
        Budget {
            items: uncertainty::TABLE2
                .iter()
                .map(|i| (i.name.to_string(), i.mils))
                .collect(),
            file: None,
            unit_warning: None,
        }
    }

    /// The budget file at `path`, or Table 2 when there is none.
    pub fn load_or_table2(path: Option<&Path>) -> Result<Budget, BudgetError> {
        match path {
            Some(p) => Budget::load(p),
            None => Ok(Budget::table2()),
        }
    }

    /// Read a budget file (TOML, `[[item]]` tables with `name` and mils `x`, `y`, `z` or
    /// `x_plus`/`x_minus`...).
    pub fn load(path: &Path) -> Result<Budget, BudgetError> {
        let p = || path.to_path_buf();
        let text = crate::bounded::read_text(path, crate::bounded::MAX_PLAN_BYTES, "a budget file")
            .map_err(|error| BudgetError::Read { path: p(), error })?;
        let b: BudgetFile = toml::from_str(&text).map_err(|e| BudgetError::Toml {
            path: p(),
            error: e.to_string(),
        })?;
        let mut out = Vec::new();
        for it in b.item {
            if [
                it.x, it.y, it.z, it.x_plus, it.x_minus, it.y_plus, it.y_minus, it.z_plus,
                it.z_minus,
            ]
            .iter()
            .all(Option::is_none)
            {
                return Err(BudgetError::NoUncertainty {
                    path: p(),
                    item: it.name,
                });
            }
            for (axis, sym, plus, minus) in [
                ("x", it.x, it.x_plus, it.x_minus),
                ("y", it.y, it.y_plus, it.y_minus),
                ("z", it.z, it.z_plus, it.z_minus),
            ] {
                if sym.is_some() && (plus.is_some() || minus.is_some()) {
                    return Err(BudgetError::BothForms {
                        path: p(),
                        item: it.name,
                        axis,
                    });
                }
            }
            let pick = |sym: Option<f64>, side: Option<f64>| side.or(sym).unwrap_or(0.0);
            let v = [
                pick(it.x, it.x_plus),
                pick(it.x, it.x_minus),
                pick(it.y, it.y_plus),
                pick(it.y, it.y_minus),
                pick(it.z, it.z_plus),
                pick(it.z, it.z_minus),
            ];
            if let Some(bad) = v
                .iter()
                .find(|m| !(m.is_finite() && **m >= 0.0 && **m <= MAX_BUDGET_MILS))
            {
                return Err(BudgetError::OutOfRange {
                    path: p(),
                    item: it.name,
                    value: *bad,
                });
            }
            out.push((it.name, v));
        }
        if out.is_empty() {
            return Err(BudgetError::Empty { path: p() });
        }
        if out.iter().all(|(_, v)| v.iter().all(|m| *m == 0.0)) {
            return Err(BudgetError::AllZero { path: p() });
        }
        let unit_warning = unit_warning(&out);
        Ok(Budget {
            items: out,
            file: Some(p()),
            unit_warning,
        })
    }

    /// The items as the uncertainty functions of `cta_core` take them.
    pub fn items(&self) -> Vec<Item<'_>> {
        self.items
            .iter()
            .map(|(n, m)| Item { name: n, mils: *m })
            .collect()
    }

    /// The root-sum-square per side, mils (eq 26): X+, X-, Y+, Y-, Z+, Z-.
    pub fn rss(&self) -> [f64; 6] {
        uncertainty::rss(&self.items())
    }

    /// The 1-sigma position uncertainty per axis, inches (eq 26, the larger side).
    pub fn rss_inches(&self) -> [f64; 3] {
        uncertainty::rss_inches(&self.items())
    }

    /// Where the budget comes from, for output: "thesis Table 2" or the file.
    pub fn source(&self) -> String {
        match &self.file {
            Some(p) => p.display().to_string(),
            None => "thesis Table 2".into(),
        }
    }
}

/// A caution when a budget's values look like inches rather than mils: every value below
/// 0.1 mil (Table 2's items are 0.5-21 mils; 0.005 in is 5 mils), or one above 1 in.
fn unit_warning(items: &[(String, [f64; 6])]) -> Option<String> {
    let values = || items.iter().flat_map(|(_, v)| v.iter().copied());
    let largest = values().fold(0.0f64, f64::max);
    if largest < 0.1 {
        return Some(format!(
            "the largest uncertainty is {largest} mils: the budget is in mils (thousandths of an \
             inch; Table 2's items are 0.5-21 mils), are these inches?"
        ));
    }
    items
        .iter()
        .find(|(_, v)| v.iter().any(|m| *m > 1000.0))
        .map(|(name, v)| {
            format!(
                "item `{name}`: {} mils is more than 1 in: the budget is in mils (Table 2's items are \
                 0.5-21 mils)",
                v.iter().copied().fold(0.0f64, f64::max)
            )
        })
}
