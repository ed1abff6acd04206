//! `[cutting]`: the stock the tool removes, the tool, the material and the spindle speed when
//! the program does not give one.

use super::limits;
use super::source::{InFile, Num};
use crate::cutting::{material, Coefficients, CuttingSpec, StockSpec, ToolShape, ToolSpec};
use crate::diagnostics::FileError;
use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCutting {
    /// Spindle speed when the program gives none (rev/min).
    spindle_rpm: Option<Num>,
    stock: Spanned<RawStock>,
    tool: Spanned<RawTool>,
    material: Spanned<RawMaterial>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStock {
    box_mm: Option<Spanned<[[f64; 3]; 2]>>,
    resolution_mm: Option<Num>,
    stl: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTool {
    diameter_mm: Option<Num>,
    flutes: Spanned<i64>,
    #[serde(default)]
    helix_deg: Option<Num>,
    flute_length_mm: Num,
    #[serde(default)]
    shape: Option<Spanned<String>>,
    corner_radius_mm: Option<Num>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    name: Option<Spanned<String>>,
    ktc_n_mm2: Option<Num>,
    krc_n_mm2: Option<Num>,
    kac_n_mm2: Option<Num>,
    kte_n_mm: Option<Num>,
    kre_n_mm: Option<Num>,
    kae_n_mm: Option<Num>,
}

impl TryFrom<InFile<'_, &RawCutting>> for CuttingSpec {
    type Error = FileError;

    fn try_from(InFile { raw, file }: InFile<'_, &RawCutting>) -> Result<Self, FileError> {
        let spindle_rpm = file.ranged_opt(
            raw.spindle_rpm.as_ref(),
            "cutting.spindle_rpm",
            "rev/min",
            limits::SPINDLE_RPM,
        )?;
        let stock = stock(raw.stock.get_ref(), raw.stock.span(), file)?;
        let tool = tool(raw.tool.get_ref(), file)?;
        if let Some(d) = tool.diameter {
            let size = stock.max - stock.min;
            if d > size.x.max(size.y).max(size.z) && stock.stl.is_none() {
                return Err(file.error(
                    raw.tool.span(),
                    format!(
                        "cutting.tool: diameter {:?} mm is wider than every side of the stock ({:?} × {:?} × {:?} mm): expected a tool narrower than the stock",
                        d * 1e3, size.x * 1e3, size.y * 1e3, size.z * 1e3
                    ),
                ));
            }
        }
        let (coefficients, material_name) =
            coefficients(raw.material.get_ref(), raw.material.span(), file)?;
        Ok(CuttingSpec {
            stock,
            tool,
            coefficients,
            material_name,
            spindle_rpm,
        })
    }
}

fn stock(
    raw: &RawStock,
    span: std::ops::Range<usize>,
    file: &super::source::Source<'_>,
) -> Result<StockSpec, FileError> {
    let resolution = file
        .ranged_opt(
            raw.resolution_mm.as_ref(),
            "cutting.stock.resolution_mm",
            "mm",
            limits::STOCK_RESOLUTION_MM,
        )?
        .unwrap_or(0.1)
        * 1e-3;
    let stl = raw.stl.as_ref().map(|s| {
        let path = file.resolve(s.get_ref());
        (path, s.span())
    });
    if let Some((path, at)) = &stl {
        if !path.is_file() {
            return Err(file.error(
                at.clone(),
                format!("cutting.stock.stl: '{}' not found", path.display()),
            ));
        }
    }
    let (min, max) = match (&raw.box_mm, &stl) {
        (Some(b), _) => {
            let [lo, hi] = *b.get_ref();
            for k in 0..3 {
                for v in [lo[k], hi[k]] {
                    if !(v.is_finite() && v.abs() <= limits::COORDINATE_MM) {
                        return Err(file.error(
                            b.span(),
                            format!("cutting.stock.box_mm: {v:?} mm: expected finite coordinates within ±{} mm", limits::COORDINATE_MM),
                        ));
                    }
                }
                if hi[k] <= lo[k] {
                    return Err(file.error(
                        b.span(),
                        format!(
                            "cutting.stock.box_mm: the second corner must lie above the first on every axis, found {} from {:?} to {:?} mm",
                            ["x", "y", "z"][k], lo[k], hi[k]
                        ),
                    ));
                }
            }
            (
                nalgebra::Point3::from(lo.map(|v| v * 1e-3)),
                nalgebra::Point3::from(hi.map(|v| v * 1e-3)),
            )
        }
        (None, Some(_)) => (nalgebra::Point3::origin(), nalgebra::Point3::origin()),
        (None, None) => {
            return Err(file.error(
                span,
                "[cutting.stock]: expected box_mm = [[x0, y0, z0], [x1, y1, z1]] (program frame, mm) or stl = \"PATH\"",
            ))
        }
    };
    Ok(StockSpec {
        min,
        max,
        resolution,
        stl: stl.map(|(p, _)| p),
    })
}

fn tool(raw: &RawTool, file: &super::source::Source<'_>) -> Result<ToolSpec, FileError> {
    let diameter = file
        .ranged_opt(
            raw.diameter_mm.as_ref(),
            "cutting.tool.diameter_mm",
            "mm",
            limits::TOOL_DIAMETER_MM,
        )?
        .map(|d| d * 1e-3);
    let flutes = *raw.flutes.get_ref();
    if !(1..=limits::MAX_FLUTES).contains(&flutes) {
        return Err(file.error(
            raw.flutes.span(),
            format!(
                "cutting.tool.flutes = {flutes}: expected a whole number from 1 to {} (the teeth of the cutter)",
                limits::MAX_FLUTES
            ),
        ));
    }
    let helix = file
        .ranged_opt(
            raw.helix_deg.as_ref(),
            "cutting.tool.helix_deg",
            "deg",
            limits::HELIX_DEG,
        )?
        .unwrap_or(0.0)
        .to_radians();
    let flute_length = file.ranged(
        &raw.flute_length_mm,
        "cutting.tool.flute_length_mm",
        "mm",
        limits::TOOL_DIAMETER_MM,
    )? * 1e-3;
    let corner = file
        .ranged_opt(
            raw.corner_radius_mm.as_ref(),
            "cutting.tool.corner_radius_mm",
            "mm",
            limits::TOOL_DIAMETER_MM,
        )?
        .map(|r| r * 1e-3);
    let shape = match raw.shape.as_ref().map(|s| (s.get_ref().as_str(), s.span())) {
        None | Some(("flat", _)) => ToolShape::Flat,
        Some(("ball", _)) => ToolShape::Ball,
        Some(("bull", at)) => match corner {
            Some(r) => {
                if let Some(d) = diameter.filter(|d| r >= 0.5 * d) {
                    return Err(file.error(
                        at,
                        format!("cutting.tool: corner_radius_mm = {:?} must be below the tool's radius {:?} mm (a corner of the full radius is shape = \"ball\")", r * 1e3, d * 0.5e3),
                    ));
                }
                ToolShape::Bull { corner_radius: r }
            }
            None => {
                return Err(file.error(at, "cutting.tool: shape = \"bull\" needs corner_radius_mm"))
            }
        },
        Some((other, at)) => {
            return Err(file.error(
                at,
                format!(
                    "cutting.tool.shape = \"{other}\": expected \"flat\", \"ball\" or \"bull\""
                ),
            ))
        }
    };
    Ok(ToolSpec {
        diameter,
        flutes: flutes as u32,
        helix,
        flute_length,
        shape,
    })
}

fn coefficients(
    raw: &RawMaterial,
    span: std::ops::Range<usize>,
    file: &super::source::Source<'_>,
) -> Result<(Coefficients, Option<String>), FileError> {
    let explicit = [
        &raw.ktc_n_mm2,
        &raw.krc_n_mm2,
        &raw.kac_n_mm2,
        &raw.kte_n_mm,
        &raw.kre_n_mm,
        &raw.kae_n_mm,
    ];
    let given = explicit.iter().filter(|k| k.is_some()).count();
    match (&raw.name, given) {
        (Some(name), 0) => match material(name.get_ref()) {
            Some(entry) => Ok((entry.coefficients, Some(entry.name.to_string()))),
            None => Err(file.error(
                name.span(),
                format!(
                    "cutting.material.name = \"{}\": expected one of {} (or the six coefficients ktc_n_mm2, krc_n_mm2, kac_n_mm2, kte_n_mm, kre_n_mm, kae_n_mm)",
                    name.get_ref(),
                    crate::cutting::MATERIALS
                        .iter()
                        .map(|m| format!("\"{}\"", m.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        },
        (None, 6) => {
            let value = |k: &Option<Num>| k.as_ref().map_or(0.0, |v| *v.get_ref());
            let c = Coefficients {
                ktc: value(&raw.ktc_n_mm2) * 1e6,
                krc: value(&raw.krc_n_mm2) * 1e6,
                kac: value(&raw.kac_n_mm2) * 1e6,
                kte: value(&raw.kte_n_mm) * 1e3,
                kre: value(&raw.kre_n_mm) * 1e3,
                kae: value(&raw.kae_n_mm) * 1e3,
            };
            c.validate().map_err(|e| file.error(span, format!("cutting.material: {e}")))?;
            Ok((c, None))
        }
        (Some(name), _) => Err(file.error(
            name.span(),
            "cutting.material: give either name or the six coefficients, not both",
        )),
        (None, n) => Err(file.error(
            span,
            format!("cutting.material: expected name = \"al7075\" (or another of the table) or all six coefficients ktc_n_mm2, krc_n_mm2, kac_n_mm2, kte_n_mm, kre_n_mm, kae_n_mm; found {n} of them"),
        )),
    }
}
