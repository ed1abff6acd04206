//! Cutting-force coefficients of the linear edge-force model and the table of work materials
//! they were identified for.
//!
//! The model (Altintas, *Manufacturing Automation*, ch. 2) gives the force on an edge element
//! of width `db` cutting a chip of thickness `h` as `K_c·h·db + K_e·db` in each of the
//! tangential, radial and axial directions: `K_c` (N/m²) is the cutting (shearing) part,
//! `K_e` (N/m) the edge (ploughing, rubbing) part. Coefficients are identified for one
//! material *with one tool geometry* (rake, helix, edge preparation, coating): a table entry
//! says which, because using them with a different tool is an approximation.

use std::fmt;

/// N/mm² → N/m².
const PER_MM2: f64 = 1.0e6;
/// N/mm → N/m.
const PER_MM: f64 = 1.0e3;

/// Accepted range of the tangential cutting coefficient `K_tc` (N/m²): 10…10 000 N/mm².
/// Below it nothing metallic is cut; above it the value was almost surely entered in the
/// wrong unit (N/m² mistaken for N/mm², or the reverse is caught by the lower bound).
pub const KTC_RANGE: (f64, f64) = (10.0 * PER_MM2, 10_000.0 * PER_MM2);
/// Accepted range of the radial and axial cutting coefficients `K_rc`, `K_ac` (N/m²):
/// 0…10 000 N/mm² (they can be small, but not negative in this model's sign convention).
pub const KRC_KAC_RANGE: (f64, f64) = (0.0, 10_000.0 * PER_MM2);
/// Accepted range of the edge coefficients `K_te`, `K_re`, `K_ae` (N/m): 0…1 000 N/mm.
pub const EDGE_RANGE: (f64, f64) = (0.0, 1_000.0 * PER_MM);

/// Cutting-force coefficients of the linear edge-force model, in SI units: N/m² for the
/// cutting coefficients (force per chip area), N/m for the edge coefficients (force per
/// edge length). Divide by 10⁶ (resp. 10³) for the N/mm² (N/mm) of the literature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coefficients {
    /// Tangential cutting coefficient `K_tc` (N/m²).
    pub ktc: f64,
    /// Radial cutting coefficient `K_rc` (N/m²).
    pub krc: f64,
    /// Axial cutting coefficient `K_ac` (N/m²).
    pub kac: f64,
    /// Tangential edge coefficient `K_te` (N/m).
    pub kte: f64,
    /// Radial edge coefficient `K_re` (N/m).
    pub kre: f64,
    /// Axial edge coefficient `K_ae` (N/m).
    pub kae: f64,
}

impl Coefficients {
    /// Coefficients from the literature's units: cutting ones in N/mm², edge ones in N/mm.
    pub const fn from_n_per_mm(ktc: f64, krc: f64, kac: f64, kte: f64, kre: f64, kae: f64) -> Self {
        Coefficients {
            ktc: ktc * PER_MM2,
            krc: krc * PER_MM2,
            kac: kac * PER_MM2,
            kte: kte * PER_MM,
            kre: kre * PER_MM,
            kae: kae * PER_MM,
        }
    }

    /// Checks every coefficient is finite and within its accepted range ([`KTC_RANGE`],
    /// [`KRC_KAC_RANGE`], [`EDGE_RANGE`]); the first one outside is named in the error.
    pub fn validate(&self) -> Result<(), CoefficientError> {
        let checks: [(&'static str, f64, (f64, f64), Unit); 6] = [
            ("K_tc", self.ktc, KTC_RANGE, Unit::PerArea),
            ("K_rc", self.krc, KRC_KAC_RANGE, Unit::PerArea),
            ("K_ac", self.kac, KRC_KAC_RANGE, Unit::PerArea),
            ("K_te", self.kte, EDGE_RANGE, Unit::PerLength),
            ("K_re", self.kre, EDGE_RANGE, Unit::PerLength),
            ("K_ae", self.kae, EDGE_RANGE, Unit::PerLength),
        ];
        for (name, value, (min, max), unit) in checks {
            // `!(a <= b)` rather than `a > b` so that NaN is refused too.
            if !(value.is_finite() && min <= value && value <= max) {
                return Err(CoefficientError {
                    name,
                    value,
                    min,
                    max,
                    unit,
                });
            }
        }
        Ok(())
    }
}

/// The unit a coefficient is reported in (the literature's, for readable messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// A cutting coefficient, shown in N/mm².
    PerArea,
    /// An edge coefficient, shown in N/mm.
    PerLength,
}

impl Unit {
    fn scale(self) -> f64 {
        match self {
            Unit::PerArea => PER_MM2,
            Unit::PerLength => PER_MM,
        }
    }

    fn symbol(self) -> &'static str {
        match self {
            Unit::PerArea => "N/mm²",
            Unit::PerLength => "N/mm",
        }
    }
}

/// A coefficient refused by [`Coefficients::validate`]. Values are held in SI units
/// (N/m², N/m); the message shows them in N/mm² or N/mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoefficientError {
    /// The coefficient's name, e.g. `"K_tc"`.
    pub name: &'static str,
    /// The refused value (SI).
    pub value: f64,
    /// Smallest accepted value (SI).
    pub min: f64,
    /// Largest accepted value (SI).
    pub max: f64,
    /// The unit used in the message.
    pub unit: Unit,
}

impl fmt::Display for CoefficientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.unit.scale();
        let u = self.unit.symbol();
        write!(
            f,
            "cutting-force coefficient {} = {} {u} is outside the accepted range {}…{} {u}",
            self.name,
            self.value / s,
            self.min / s,
            self.max / s
        )
    }
}

impl std::error::Error for CoefficientError {}

/// One work material of the table: its coefficients and where they come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialEntry {
    /// Short key used in scenarios, e.g. `"al7075"`.
    pub name: &'static str,
    /// What the material is (alloy, temper).
    pub description: &'static str,
    /// The coefficients (SI).
    pub coefficients: Coefficients,
    /// The publication, table and tool the coefficients were identified with.
    pub source: &'static str,
}

/// The work materials with published coefficients (docs/cutting.md has the table and how each
/// set was checked). Only values that can be attributed to a publication are listed: for AISI
/// 1045 steel and Ti-6Al-4V no set of the six coefficients could be confirmed, so they are
/// not here, and a scenario gives them explicitly.
pub const MATERIALS: &[MaterialEntry] = &[
    MaterialEntry {
        name: "al7075",
        description: "Aluminium alloy 7075-T6",
        coefficients: Coefficients::from_n_per_mm(796.0, 168.8, 222.0, 27.7, 30.8, 1.4),
        source: "Y. Altintas, Manufacturing Automation, Cambridge University Press (2000; 2nd \
                 ed. 2012), ch. 2: the average-force (slot milling) identification of the \
                 linear edge-force model for Al7075-T6 with a carbide helical end mill. K_tc, \
                 K_rc, K_ac and K_te agree in every reproduction found; K_re (30.8) and K_ae \
                 (1.4) as reproduced in milling-force codes, where a review's table has 26.6 \
                 and 0.7 for the same alloy (see al7075_review).",
    },
    MaterialEntry {
        name: "al7075_review",
        description: "Aluminium alloy 7075-T6, carbide tool, dry",
        coefficients: Coefficients::from_n_per_mm(767.01, 168.8, 222.0, 27.7, 26.6, 0.7),
        source: "Review 'Milling Force Model for Aviation Aluminum Alloy: Academic Insight and \
                 Perspective Analysis', Chinese Journal of Mechanical Engineering 34 (2021), \
                 doi:10.1186/s10033-021-00536-9, Table 5 (carbide, dry; as the review quotes \
                 its reference 190).",
    },
    MaterialEntry {
        name: "al6082",
        description: "Aluminium alloy 6082-T6, carbide tool, dry",
        coefficients: Coefficients::from_n_per_mm(631.0, 99.0, 273.0, 13.0, 10.0, 2.8),
        source: "Review 'Milling Force Model for Aviation Aluminum Alloy: Academic Insight and \
                 Perspective Analysis', Chinese Journal of Mechanical Engineering 34 (2021), \
                 doi:10.1186/s10033-021-00536-9, Table 5 (carbide, dry; as the review quotes \
                 its reference 189).",
    },
    MaterialEntry {
        name: "al6061",
        description: "Aluminium alloy 6061-T6, cemented carbide tool, dry (no axial terms)",
        coefficients: Coefficients::from_n_per_mm(243.77, 113.5, 0.0, 7.53, 7.83, 0.0),
        source: "Review 'Milling Force Model for Aviation Aluminum Alloy: Academic Insight and \
                 Perspective Analysis', Chinese Journal of Mechanical Engineering 34 (2021), \
                 doi:10.1186/s10033-021-00536-9, Table 5 (cemented carbide, dry; as the review \
                 quotes its reference 160). The source gives no axial coefficients: the axial \
                 force is zero with this set.",
    },
];

/// The table entry called `name` (case-insensitive), if any.
pub fn material(name: &str) -> Option<&'static MaterialEntry> {
    MATERIALS.iter().find(|m| m.name.eq_ignore_ascii_case(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn al7075() -> Coefficients {
        material("al7075")
            .map(|m| m.coefficients)
            .unwrap_or(Coefficients {
                ktc: 0.0,
                krc: 0.0,
                kac: 0.0,
                kte: 0.0,
                kre: 0.0,
                kae: 0.0,
            })
    }

    #[test]
    fn table_entries_validate_and_are_unique() {
        for (i, m) in MATERIALS.iter().enumerate() {
            assert!(m.coefficients.validate().is_ok(), "{} refused", m.name);
            assert!(!m.source.is_empty() && !m.description.is_empty());
            assert!(
                MATERIALS[..i].iter().all(|o| o.name != m.name),
                "duplicate {}",
                m.name
            );
        }
        assert!(material("AL7075").is_some());
        assert!(material("unobtainium").is_none());
    }

    #[test]
    fn al7075_is_in_si_units() {
        let c = al7075();
        assert_eq!(c.ktc, 796.0e6);
        assert_eq!(c.kte, 27.7e3);
        assert!((c.kae - 1.4e3).abs() < 1e-9);
    }

    #[test]
    fn validation_refuses_and_names_the_coefficient() {
        let good = al7075();
        let cases: [(Coefficients, &str); 8] = [
            (Coefficients { ktc: -1.0, ..good }, "K_tc"),
            (Coefficients { ktc: 5.0e6, ..good }, "K_tc"), // 5 N/mm²: too small
            (
                Coefficients {
                    ktc: 2.0e10,
                    ..good
                },
                "K_tc",
            ), // 20 000 N/mm²
            (Coefficients { ktc: 796.0, ..good }, "K_tc"), // N/mm² typed as N/m²
            (
                Coefficients {
                    krc: f64::NAN,
                    ..good
                },
                "K_rc",
            ),
            (
                Coefficients {
                    kac: -3.0e6,
                    ..good
                },
                "K_ac",
            ),
            (Coefficients { kre: 2.0e6, ..good }, "K_re"), // 2 000 N/mm
            (
                Coefficients {
                    kae: f64::INFINITY,
                    ..good
                },
                "K_ae",
            ),
        ];
        for (c, name) in cases {
            let err = c.validate().expect_err(name);
            assert_eq!(err.name, name);
            let msg = err.to_string();
            assert!(msg.contains(name) && msg.contains("N/mm"), "{msg}");
        }
        let e = Coefficients { kte: -1.0, ..good }
            .validate()
            .expect_err("kte");
        assert_eq!(
            e.to_string(),
            "cutting-force coefficient K_te = -0.001 N/mm is outside the accepted range 0…1000 N/mm"
        );
        assert!(good.validate().is_ok());
    }
}
