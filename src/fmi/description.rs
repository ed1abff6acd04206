//! The parts of an FMU's `modelDescription.xml` a co-simulation master needs: the FMI
//! version, the co-simulation interface, and the real-valued variables with their units.

use std::collections::BTreeMap;

/// The FMI version an FMU implements.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    /// FMI 2.0.
    Fmi2,
    /// FMI 3.0.
    Fmi3,
}

impl FmiVersion {
    /// The version as the standard writes it.
    pub fn name(self) -> &'static str {
        match self {
            FmiVersion::Fmi2 => "2.0",
            FmiVersion::Fmi3 => "3.0",
        }
    }
}

/// What a variable is to the master (FMI `causality`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// A value the master may set before the run (`parameter`).
    Parameter,
    /// A value the FMU computes from parameters (`calculatedParameter`).
    CalculatedParameter,
    /// A value the master sets during the run (`input`).
    Input,
    /// A value the FMU gives the master (`output`).
    Output,
    /// An internal value the master may read but need not (`local`).
    Local,
    /// The independent variable, time (`independent`).
    Independent,
    /// A parameter that changes the FMU's structure, such as array sizes (FMI 3.0
    /// `structuralParameter`).
    StructuralParameter,
}

impl Causality {
    fn parse(s: &str) -> Option<Causality> {
        Some(match s {
            "parameter" => Causality::Parameter,
            "calculatedParameter" => Causality::CalculatedParameter,
            "input" => Causality::Input,
            "output" => Causality::Output,
            "local" => Causality::Local,
            "independent" => Causality::Independent,
            "structuralParameter" => Causality::StructuralParameter,
            _ => return None,
        })
    }

    /// The name the standard uses.
    pub fn name(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
            Causality::Independent => "independent",
            Causality::StructuralParameter => "structuralParameter",
        }
    }
}

/// One model variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// The variable's name.
    pub name: String,
    /// The handle the FMU's get and set functions take for this variable (`valueReference`).
    pub value_reference: u32,
    /// What the variable is to the master.
    pub causality: Causality,
    /// `fixed`, `tunable`, `continuous`, …, as written (default `continuous`).
    pub variability: String,
    /// The element type: `Float64`, `Float32`, `Int32`, … for FMI 3.0; `Real`, `Integer`, … for
    /// FMI 2.0.
    pub type_name: String,
    /// The unit, given on the variable or through its declared type.
    pub unit: Option<String>,
    /// The declared type's name, if any.
    pub declared_type: Option<String>,
}

impl Variable {
    /// Whether the variable is a 64-bit float (`Float64` in 3.0, `Real` in 2.0).
    pub fn is_float64(&self) -> bool {
        self.type_name == "Float64" || self.type_name == "Real"
    }
}

/// A unit definition's SI base-unit exponents and factor/offset (FMI `BaseUnit`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BaseUnit {
    /// Exponents of kg, m, s, A, K, mol, cd, rad.
    pub exponents: [i32; 8],
    /// Factor of the conversion to SI: value in SI = `factor` · value + `offset`.
    pub factor: f64,
    /// Offset of the conversion to SI, in SI units (see `factor`).
    pub offset: f64,
}

/// The model description of a co-simulation FMU.
#[derive(Debug, Clone)]
pub struct ModelDescription {
    /// The FMI version the FMU implements.
    pub version: FmiVersion,
    /// The model's name (`modelName`; empty when not given).
    pub model_name: String,
    /// `instantiationToken` (3.0) or `guid` (2.0).
    pub token: String,
    /// The co-simulation interface's model identifier (the shared library's name).
    pub model_identifier: String,
    /// The model variables, in the order the file lists them.
    pub variables: Vec<Variable>,
    /// Unit definitions that give their base units.
    pub units: BTreeMap<String, BaseUnit>,
}

impl ModelDescription {
    /// Reads a model description. Errors say what is missing or malformed.
    pub fn parse(xml: &str) -> Result<ModelDescription, String> {
        let doc = roxmltree::Document::parse(xml)
            .map_err(|e| format!("modelDescription.xml is not well-formed XML: {e}"))?;
        let root = doc.root_element();
        if root.tag_name().name() != "fmiModelDescription" {
            return Err(format!(
                "modelDescription.xml: the root element is <{}>, not <fmiModelDescription>",
                root.tag_name().name()
            ));
        }
        let version_text = root.attribute("fmiVersion").unwrap_or("");
        let version = if version_text.starts_with("3.") {
            FmiVersion::Fmi3
        } else if version_text == "2.0" {
            FmiVersion::Fmi2
        } else {
            return Err(format!(
                "fmiVersion = \"{version_text}\": cncsim imports FMI 2.0 and 3.0 FMUs"
            ));
        };
        let token_key = match version {
            FmiVersion::Fmi3 => "instantiationToken",
            FmiVersion::Fmi2 => "guid",
        };
        let token = root
            .attribute(token_key)
            .ok_or_else(|| format!("modelDescription.xml has no {token_key}"))?
            .to_string();
        let child = |name: &str| root.children().find(|n| n.has_tag_name(name));
        let Some(cs) = child("CoSimulation") else {
            let kinds: Vec<&str> = ["ModelExchange", "ScheduledExecution"]
                .into_iter()
                .filter(|k| child(k).is_some())
                .collect();
            return Err(format!(
                "not a co-simulation FMU (it has no <CoSimulation> interface{}): cncsim steps the controller once per servo period and needs one",
                if kinds.is_empty() {
                    String::new()
                } else {
                    format!("; it offers {}", kinds.join(", "))
                }
            ));
        };
        let model_identifier = cs
            .attribute("modelIdentifier")
            .ok_or("<CoSimulation> has no modelIdentifier")?
            .to_string();

        let mut units = BTreeMap::new();
        for unit in child("UnitDefinitions")
            .into_iter()
            .flat_map(|u| u.children().filter(|n| n.has_tag_name("Unit")))
        {
            let Some(name) = unit.attribute("name") else {
                continue;
            };
            if let Some(base) = unit.children().find(|n| n.has_tag_name("BaseUnit")) {
                let mut b = BaseUnit {
                    factor: 1.0,
                    ..BaseUnit::default()
                };
                for (i, key) in ["kg", "m", "s", "A", "K", "mol", "cd", "rad"]
                    .iter()
                    .enumerate()
                {
                    if let Some(v) = base.attribute(*key) {
                        b.exponents[i] = v.parse().map_err(|_| {
                            format!("unit '{name}': BaseUnit {key} = \"{v}\" is not an integer")
                        })?;
                    }
                }
                let number = |key: &str, default: f64| -> Result<f64, String> {
                    base.attribute(key).map_or(Ok(default), |v| {
                        v.parse().map_err(|_| {
                            format!("unit '{name}': BaseUnit {key} = \"{v}\" is not a number")
                        })
                    })
                };
                b.factor = number("factor", 1.0)?;
                b.offset = number("offset", 0.0)?;
                units.insert(name.to_string(), b);
            }
        }

        // Declared types and their units.
        let mut type_units: BTreeMap<String, String> = BTreeMap::new();
        for t in child("TypeDefinitions")
            .into_iter()
            .flat_map(|t| t.children().filter(|n| n.is_element()))
        {
            let Some(name) = t.attribute("name") else {
                continue;
            };
            // 3.0: <Float64Type name unit/>; 2.0: <SimpleType name><Real unit/></SimpleType>.
            let unit = t.attribute("unit").or_else(|| {
                t.children()
                    .find(|n| n.is_element())
                    .and_then(|n| n.attribute("unit"))
            });
            if let Some(unit) = unit {
                type_units.insert(name.to_string(), unit.to_string());
            }
        }

        let vars = child("ModelVariables").ok_or("modelDescription.xml has no <ModelVariables>")?;
        let mut variables = Vec::new();
        for v in vars.children().filter(|n| n.is_element()) {
            // 2.0 wraps the type element in <ScalarVariable>.
            let (element, type_name) = match version {
                FmiVersion::Fmi3 => (v, v.tag_name().name().to_string()),
                FmiVersion::Fmi2 => {
                    let Some(t) = v.children().find(|n| n.is_element()) else {
                        continue;
                    };
                    (t, t.tag_name().name().to_string())
                }
            };
            let name = v
                .attribute("name")
                .ok_or("a model variable has no name")?
                .to_string();
            let value_reference = v
                .attribute("valueReference")
                .and_then(|r| r.parse().ok())
                .ok_or_else(|| format!("variable '{name}' has no valid valueReference"))?;
            let causality_text = v.attribute("causality").unwrap_or("local");
            let causality = Causality::parse(causality_text).ok_or_else(|| {
                format!("variable '{name}': unknown causality \"{causality_text}\"")
            })?;
            let declared_type = element.attribute("declaredType").map(str::to_string);
            let unit = element.attribute("unit").map(str::to_string).or_else(|| {
                declared_type
                    .as_ref()
                    .and_then(|t| type_units.get(t))
                    .cloned()
            });
            variables.push(Variable {
                name,
                value_reference,
                causality,
                variability: v.attribute("variability").unwrap_or("continuous").into(),
                type_name,
                unit,
                declared_type,
            });
        }
        Ok(ModelDescription {
            version,
            model_name: root.attribute("modelName").unwrap_or("").to_string(),
            token,
            model_identifier,
            variables,
            units,
        })
    }

    /// The variable called `name`.
    pub fn variable(&self, name: &str) -> Option<&Variable> {
        self.variables.iter().find(|v| v.name == name)
    }
}

/// A physical quantity cncsim exchanges, with its SI unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Position on a linear axis (m).
    Length,
    /// Velocity on a linear axis (m/s).
    Velocity,
    /// Acceleration on a linear axis (m/s²).
    Acceleration,
    /// Position on a rotary axis (rad).
    Angle,
    /// Velocity on a rotary axis (rad/s).
    AngularVelocity,
    /// Acceleration on a rotary axis (rad/s²).
    AngularAcceleration,
    /// Voltage (V), such as a drive's command.
    Voltage,
    /// Torque (N·m).
    Torque,
}

impl Quantity {
    /// The SI unit cncsim uses, as FMI writes unit names.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Length => "m",
            Quantity::Velocity => "m/s",
            Quantity::Acceleration => "m/s2",
            Quantity::Angle => "rad",
            Quantity::AngularVelocity => "rad/s",
            Quantity::AngularAcceleration => "rad/s2",
            Quantity::Voltage => "V",
            Quantity::Torque => "N.m",
        }
    }

    /// Spellings of the unit's name taken as this quantity's SI unit when the unit has no
    /// `BaseUnit` definition.
    fn spellings(self) -> &'static [&'static str] {
        match self {
            Quantity::Length => &["m"],
            Quantity::Velocity => &["m/s", "m.s-1"],
            Quantity::Acceleration => &["m/s2", "m/s^2", "m.s-2", "m/s/s"],
            Quantity::Angle => &["rad"],
            Quantity::AngularVelocity => &["rad/s", "rad.s-1"],
            Quantity::AngularAcceleration => &["rad/s2", "rad/s^2", "rad.s-2"],
            Quantity::Voltage => &["V"],
            Quantity::Torque => &["N.m", "N·m", "Nm", "N*m"],
        }
    }

    /// Exponents of kg, m, s, A, K, mol, cd, rad (radians may be left out: FMI tools often
    /// treat them as dimensionless).
    fn exponents(self) -> [i32; 8] {
        match self {
            Quantity::Length => [0, 1, 0, 0, 0, 0, 0, 0],
            Quantity::Velocity => [0, 1, -1, 0, 0, 0, 0, 0],
            Quantity::Acceleration => [0, 1, -2, 0, 0, 0, 0, 0],
            Quantity::Angle => [0, 0, 0, 0, 0, 0, 0, 1],
            Quantity::AngularVelocity => [0, 0, -1, 0, 0, 0, 0, 1],
            Quantity::AngularAcceleration => [0, 0, -2, 0, 0, 0, 0, 1],
            Quantity::Voltage => [1, 2, -3, -1, 0, 0, 0, 0],
            Quantity::Torque => [1, 2, -2, 0, 0, 0, 0, 0],
        }
    }

    /// Whether `unit`, as `description` defines it, is this quantity's SI unit. `Ok` when the
    /// variable gives no unit (nothing to check).
    pub fn check(self, unit: Option<&str>, description: &ModelDescription) -> Result<(), String> {
        let Some(unit) = unit else {
            return Ok(());
        };
        let matches = match description.units.get(unit) {
            Some(base) => {
                let mut want = self.exponents();
                let mut have = base.exponents;
                // Radians are dimensionless to many tools: compare without them.
                want[7] = 0;
                have[7] = 0;
                want == have && base.factor == 1.0 && base.offset == 0.0
            }
            None => self.spellings().contains(&unit),
        };
        if matches {
            Ok(())
        } else {
            Err(format!(
                "its unit is \"{unit}\", cncsim exchanges {} (SI)",
                self.unit()
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FMI3: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="3.0" modelName="pid" instantiationToken="{abc}">
  <CoSimulation modelIdentifier="pid"/>
  <UnitDefinitions>
    <Unit name="mm"><BaseUnit m="1" factor="0.001"/></Unit>
    <Unit name="volt"><BaseUnit kg="1" m="2" s="-3" A="-1"/></Unit>
  </UnitDefinitions>
  <TypeDefinitions><Float64Type name="Position" unit="m"/></TypeDefinitions>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent"/>
    <Float64 name="kp" valueReference="1" causality="parameter" variability="tunable" start="1"/>
    <Float64 name="setpoint_position_x" valueReference="2" causality="input" declaredType="Position" start="0"/>
    <Float64 name="measured_position_x" valueReference="3" causality="input" unit="mm" start="0"/>
    <Float64 name="command_x" valueReference="4" causality="output" unit="volt"/>
  </ModelVariables>
</fmiModelDescription>"#;

    #[test]
    fn reads_variables_units_and_declared_types() {
        let d = ModelDescription::parse(FMI3).unwrap();
        assert_eq!(d.version, FmiVersion::Fmi3);
        assert_eq!(d.model_identifier, "pid");
        assert_eq!(d.token, "{abc}");
        let sp = d.variable("setpoint_position_x").unwrap();
        assert_eq!(sp.unit.as_deref(), Some("m"));
        assert_eq!(sp.causality, Causality::Input);
        assert!(Quantity::Length.check(sp.unit.as_deref(), &d).is_ok());
        let mm = d.variable("measured_position_x").unwrap();
        let err = Quantity::Length.check(mm.unit.as_deref(), &d).unwrap_err();
        assert!(err.contains("\"mm\""), "{err}");
        let u = d.variable("command_x").unwrap();
        assert!(Quantity::Voltage.check(u.unit.as_deref(), &d).is_ok());
        assert!(Quantity::Torque.check(u.unit.as_deref(), &d).is_err());
    }

    #[test]
    fn refuses_model_exchange_only() {
        let xml = FMI3.replace(
            "<CoSimulation modelIdentifier=\"pid\"/>",
            "<ModelExchange modelIdentifier=\"pid\"/>",
        );
        let err = ModelDescription::parse(&xml).unwrap_err();
        assert!(err.contains("not a co-simulation FMU"), "{err}");
        assert!(err.contains("ModelExchange"), "{err}");
    }

    #[test]
    fn reads_fmi2_scalar_variables() {
        let xml = r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{g}">
  <CoSimulation modelIdentifier="m"/>
  <TypeDefinitions><SimpleType name="Voltage"><Real unit="V"/></SimpleType></TypeDefinitions>
  <ModelVariables>
    <ScalarVariable name="command_x" valueReference="7" causality="output"><Real declaredType="Voltage"/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"#;
        let d = ModelDescription::parse(xml).unwrap();
        assert_eq!(d.version, FmiVersion::Fmi2);
        let v = d.variable("command_x").unwrap();
        assert_eq!(v.value_reference, 7);
        assert!(v.is_float64());
        assert_eq!(v.unit.as_deref(), Some("V"));
    }
}
