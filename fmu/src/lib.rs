//! FMI 3.0 co-simulation interface of cncsim's plant ([`cncsim::fmi::plant::PlantModel`]): the
//! C functions of the standard (`fmi3Functions.h`), hand-written over the plant. `cncsim
//! export-fmu` packs this library into a plant FMU with a model description for the scenario
//! and the scenario's files in `resources/`.
//!
//! Co-simulation only: model exchange and scheduled execution are refused at instantiation,
//! and every function of the types the plant has no variables of returns an error (or OK for
//! zero variables), as do FMU state, clocks, derivatives and event mode.
//!
//! Not the `fmi-export` crate: it builds on fmi-sys, whose build script runs bindgen (libclang
//! on every build machine, not on CI's), for what is here about 300 lines.

#![allow(clippy::missing_safety_doc)] // C entry points: the FMI standard states their contract.

use cncsim::fmi::plant::PlantModel;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::PathBuf;

type Fmi3Status = c_int;
const OK: Fmi3Status = 0;
const ERROR: Fmi3Status = 3;

type LogMessage = unsafe extern "C" fn(*mut c_void, Fmi3Status, *const c_char, *const c_char);

use cncsim::fmi::export::TOKEN_FILE;

/// One plant FMU instance.
struct Instance {
    /// `None` after a failed step: the plant cannot go on.
    model: Option<PlantModel>,
    resources: PathBuf,
    environment: *mut c_void,
    log: Option<LogMessage>,
    /// Time of the outputs (the communication point the master is at).
    time: f64,
}

impl Instance {
    fn log(&self, status: Fmi3Status, message: &str) {
        if let Some(log) = self.log {
            let category = c"logStatusError";
            let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
            // SAFETY: the callback the master gave, with valid NUL-terminated strings.
            unsafe { log(self.environment, status, category.as_ptr(), text.as_ptr()) };
        }
    }

    fn fail(&mut self, message: &str) -> Fmi3Status {
        self.log(ERROR, message);
        ERROR
    }
}

/// The instance behind an `fmi3Instance` handle.
unsafe fn instance<'a>(handle: *mut c_void) -> Option<&'a mut Instance> {
    // SAFETY: handles are `Instance`s this library boxed (or null).
    unsafe { (handle as *mut Instance).as_mut() }
}

fn text(p: *const c_char) -> Option<String> {
    // SAFETY: FMI strings are NUL-terminated (or null).
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
}

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi3SetDebugLogging(
    _instance: *mut c_void,
    _logging_on: bool,
    _n: usize,
    _categories: *const *const c_char,
) -> Fmi3Status {
    OK
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    _name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    event_mode_used: bool,
    early_return_allowed: bool,
    _required: *const u32,
    _n_required: usize,
    environment: *mut c_void,
    log: Option<LogMessage>,
    _intermediate_update: *const c_void,
) -> *mut c_void {
    let mut instance = Instance {
        model: None,
        resources: PathBuf::new(),
        environment,
        log,
        time: 0.0,
    };
    let Some(resources) = text(resource_path) else {
        instance.log(
            ERROR,
            "the plant FMU needs its resources/ folder (resourcePath is null)",
        );
        return std::ptr::null_mut();
    };
    instance.resources = PathBuf::from(resources);
    // The plant has no events and never returns early: a master may allow both, it gets
    // neither.
    let _ = (event_mode_used, early_return_allowed);
    let expected = std::fs::read_to_string(instance.resources.join(TOKEN_FILE)).unwrap_or_default();
    if text(token).as_deref() != Some(expected.trim()) {
        instance.log(
            ERROR,
            "wrong instantiationToken: this library is not the one of this FMU's model description",
        );
        return std::ptr::null_mut();
    }
    match PlantModel::load(&instance.resources) {
        Ok(model) => {
            instance.time = model.start_time();
            instance.model = Some(model);
            Box::into_raw(Box::new(instance)) as *mut c_void
        }
        Err(e) => {
            instance.log(ERROR, &format!("loading the plant: {e}"));
            std::ptr::null_mut()
        }
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log: Option<LogMessage>,
) -> *mut c_void {
    if let Some(log) = log {
        let m = c"cncsim's plant FMU is co-simulation only (model exchange is not supported)";
        // SAFETY: the master's callback with valid strings.
        unsafe { log(environment, ERROR, c"logStatusError".as_ptr(), m.as_ptr()) };
    }
    std::ptr::null_mut()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _name: *const c_char,
    _token: *const c_char,
    _resource_path: *const c_char,
    _visible: bool,
    _logging_on: bool,
    environment: *mut c_void,
    log: Option<LogMessage>,
    _clock_update: *const c_void,
    _lock: *const c_void,
    _unlock: *const c_void,
) -> *mut c_void {
    if let Some(log) = log {
        let m = c"cncsim's plant FMU is co-simulation only (scheduled execution is not supported)";
        // SAFETY: as above.
        unsafe { log(environment, ERROR, c"logStatusError".as_ptr(), m.as_ptr()) };
    }
    std::ptr::null_mut()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(handle: *mut c_void) {
    if !handle.is_null() {
        // SAFETY: a handle this library made, freed once (the master's duty).
        drop(unsafe { Box::from_raw(handle as *mut Instance) });
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    handle: *mut c_void,
    _tolerance_defined: bool,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: bool,
    _stop_time: f64,
) -> Fmi3Status {
    // SAFETY: the master's handle.
    let Some(i) = (unsafe { instance(handle) }) else {
        return ERROR;
    };
    // The plant starts at its first tick whatever the master calls that time.
    i.time = start_time;
    OK
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(handle: *mut c_void) -> Fmi3Status {
    // SAFETY: the master's handle.
    if unsafe { instance(handle) }.is_some() {
        OK
    } else {
        ERROR
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(handle: *mut c_void) -> Fmi3Status {
    // SAFETY: the master's handle.
    if unsafe { instance(handle) }.is_some() {
        OK
    } else {
        ERROR
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(handle: *mut c_void) -> Fmi3Status {
    // SAFETY: the master's handle.
    let Some(i) = (unsafe { instance(handle) }) else {
        return ERROR;
    };
    match PlantModel::load(&i.resources) {
        Ok(model) => {
            i.time = model.start_time();
            i.model = Some(model);
            OK
        }
        Err(e) => i.fail(&format!("reloading the plant: {e}")),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    handle: *mut c_void,
    references: *const u32,
    n_references: usize,
    values: *mut f64,
    n_values: usize,
) -> Fmi3Status {
    // SAFETY: the master's handle.
    let Some(i) = (unsafe { instance(handle) }) else {
        return ERROR;
    };
    if n_references != n_values {
        return i.fail("fmi3GetFloat64: nValueReferences and nValues differ");
    }
    if n_references == 0 {
        return OK;
    }
    // SAFETY: the master passes arrays of n elements.
    let (references, values) = unsafe {
        (
            std::slice::from_raw_parts(references, n_references),
            std::slice::from_raw_parts_mut(values, n_values),
        )
    };
    let Some(model) = &i.model else {
        return i.fail("the plant stopped at a failed step");
    };
    let mut unknown = None;
    for (r, v) in references.iter().zip(values.iter_mut()) {
        match model.get(*r) {
            // `time` is the master's clock; `program_time` the plant's.
            Some(_) if *r == 0 => *v = i.time,
            Some(x) => *v = x,
            None => {
                unknown = Some(*r);
                break;
            }
        }
    }
    match unknown {
        Some(r) => i.fail(&format!(
            "fmi3GetFloat64: no variable has valueReference {r}"
        )),
        None => OK,
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    handle: *mut c_void,
    references: *const u32,
    n_references: usize,
    values: *const f64,
    n_values: usize,
) -> Fmi3Status {
    // SAFETY: the master's handle.
    let Some(i) = (unsafe { instance(handle) }) else {
        return ERROR;
    };
    if n_references != n_values {
        return i.fail("fmi3SetFloat64: nValueReferences and nValues differ");
    }
    if n_references == 0 {
        return OK;
    }
    // SAFETY: the master passes arrays of n elements.
    let (references, values) = unsafe {
        (
            std::slice::from_raw_parts(references, n_references),
            std::slice::from_raw_parts(values, n_values),
        )
    };
    let Some(model) = &mut i.model else {
        return i.fail("the plant stopped at a failed step");
    };
    let not_input = references
        .iter()
        .zip(values)
        .find(|(r, v)| !model.set(**r, **v))
        .map(|(r, _)| *r);
    match not_input {
        Some(r) => i.fail(&format!(
            "fmi3SetFloat64: valueReference {r} is not an input (the inputs are command_<axis>)"
        )),
        None => OK,
    }
}

#[no_mangle]
#[allow(clippy::too_many_arguments)] // fmi3DoStep's signature is the FMI 3.0 standard's
pub unsafe extern "C" fn fmi3DoStep(
    handle: *mut c_void,
    current_communication_point: f64,
    communication_step_size: f64,
    _no_set_fmu_state_prior: bool,
    event_handling_needed: *mut bool,
    terminate_simulation: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> Fmi3Status {
    // SAFETY: the master's handle and out-pointers.
    let Some(i) = (unsafe { instance(handle) }) else {
        return ERROR;
    };
    unsafe {
        for p in [event_handling_needed, terminate_simulation, early_return] {
            if !p.is_null() {
                *p = false;
            }
        }
        if !last_successful_time.is_null() {
            *last_successful_time = current_communication_point;
        }
    }
    let Some(period) = i.model.as_ref().map(PlantModel::period) else {
        return i.fail("the plant stopped at a failed step");
    };
    // One step is one servo period: what the servo loop holds a command over.
    if (communication_step_size - period).abs() > 1e-9 * period {
        let message = format!(
            "doStep of {communication_step_size:?} s: the plant steps one servo period, {period:?} s"
        );
        return i.fail(&message);
    }
    let stepped = i.model.as_mut().map(PlantModel::step);
    if let Some(Err(e)) = stepped {
        i.model = None;
        return i.fail(&format!(
            "the plant stopped in the step from t = {current_communication_point} s: {e}"
        ));
    }
    i.time = current_communication_point + communication_step_size;
    // SAFETY: as above.
    unsafe {
        if !last_successful_time.is_null() {
            *last_successful_time = i.time;
        }
    }
    OK
}

/// Functions the plant does not support: an error, logged.
macro_rules! unsupported {
    ($($name:ident ( $($arg:ident : $ty:ty),* );)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(handle: *mut c_void $(, $arg: $ty)*) -> Fmi3Status {
            $(let _ = $arg;)*
            // SAFETY: the master's handle.
            match unsafe { instance(handle) } {
                Some(i) => i.fail(concat!(stringify!($name), " is not supported by cncsim's plant FMU")),
                None => ERROR,
            }
        }
    )*};
}

/// Get/set of a type the plant has no variables of: fine for none, an error for any.
macro_rules! no_variables {
    ($($name:ident ( $values:ty );)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            handle: *mut c_void,
            _references: *const u32,
            n_references: usize,
            _values: $values,
            _n_values: usize,
        ) -> Fmi3Status {
            if n_references == 0 {
                return OK;
            }
            // SAFETY: the master's handle.
            match unsafe { instance(handle) } {
                Some(i) => i.fail(concat!(stringify!($name), ": the plant FMU has only Float64 variables")),
                None => ERROR,
            }
        }
    )*};
}

no_variables! {
    fmi3GetFloat32(*mut f32);
    fmi3GetInt8(*mut i8);
    fmi3GetUInt8(*mut u8);
    fmi3GetInt16(*mut i16);
    fmi3GetUInt16(*mut u16);
    fmi3GetInt32(*mut i32);
    fmi3GetUInt32(*mut u32);
    fmi3GetInt64(*mut i64);
    fmi3GetUInt64(*mut u64);
    fmi3GetBoolean(*mut bool);
    fmi3GetString(*mut *const c_char);
    fmi3SetFloat32(*const f32);
    fmi3SetInt8(*const i8);
    fmi3SetUInt8(*const u8);
    fmi3SetInt16(*const i16);
    fmi3SetUInt16(*const u16);
    fmi3SetInt32(*const i32);
    fmi3SetUInt32(*const u32);
    fmi3SetInt64(*const i64);
    fmi3SetUInt64(*const u64);
    fmi3SetBoolean(*const bool);
    fmi3SetString(*const *const c_char);
}

unsupported! {
    fmi3EnterEventMode();
    fmi3GetBinary(r: *const u32, n: usize, sizes: *mut usize, values: *mut *const u8, nv: usize);
    fmi3SetBinary(r: *const u32, n: usize, sizes: *const usize, values: *const *const u8, nv: usize);
    fmi3GetClock(r: *const u32, n: usize, values: *mut bool);
    fmi3SetClock(r: *const u32, n: usize, values: *const bool);
    fmi3GetNumberOfVariableDependencies(r: u32, n: *mut usize);
    fmi3GetVariableDependencies(d: u32, e: *mut usize, i: *mut u32, k: *mut usize, c: *mut c_int, n: usize);
    fmi3GetFMUState(state: *mut *mut c_void);
    fmi3SetFMUState(state: *mut c_void);
    fmi3FreeFMUState(state: *mut *mut c_void);
    fmi3SerializedFMUStateSize(state: *mut c_void, size: *mut usize);
    fmi3SerializeFMUState(state: *mut c_void, bytes: *mut u8, size: usize);
    fmi3DeserializeFMUState(bytes: *const u8, size: usize, state: *mut *mut c_void);
    fmi3GetDirectionalDerivative(u: *const u32, nu: usize, k: *const u32, nk: usize, s: *const f64, ns: usize, se: *mut f64, nse: usize);
    fmi3GetAdjointDerivative(u: *const u32, nu: usize, k: *const u32, nk: usize, s: *const f64, ns: usize, se: *mut f64, nse: usize);
    fmi3EnterConfigurationMode();
    fmi3ExitConfigurationMode();
    fmi3GetIntervalDecimal(r: *const u32, n: usize, i: *mut f64, q: *mut c_int);
    fmi3GetIntervalFraction(r: *const u32, n: usize, c: *mut u64, res: *mut u64, q: *mut c_int);
    fmi3GetShiftDecimal(r: *const u32, n: usize, s: *mut f64);
    fmi3GetShiftFraction(r: *const u32, n: usize, c: *mut u64, res: *mut u64);
    fmi3SetIntervalDecimal(r: *const u32, n: usize, i: *const f64);
    fmi3SetIntervalFraction(r: *const u32, n: usize, c: *const u64, res: *const u64);
    fmi3SetShiftDecimal(r: *const u32, n: usize, s: *const f64);
    fmi3SetShiftFraction(r: *const u32, n: usize, c: *const u64, res: *const u64);
    fmi3EvaluateDiscreteStates();
    fmi3UpdateDiscreteStates(a: *mut bool, b: *mut bool, c: *mut bool, d: *mut bool, e: *mut bool, f: *mut f64);
    fmi3EnterContinuousTimeMode();
    fmi3CompletedIntegratorStep(a: bool, b: *mut bool, c: *mut bool);
    fmi3SetTime(t: f64);
    fmi3SetContinuousStates(x: *const f64, n: usize);
    fmi3GetContinuousStateDerivatives(x: *mut f64, n: usize);
    fmi3GetEventIndicators(x: *mut f64, n: usize);
    fmi3GetContinuousStates(x: *mut f64, n: usize);
    fmi3GetNominalsOfContinuousStates(x: *mut f64, n: usize);
    fmi3GetNumberOfEventIndicators(n: *mut usize);
    fmi3GetNumberOfContinuousStates(n: *mut usize);
    fmi3EnterStepMode();
    fmi3GetOutputDerivatives(r: *const u32, n: usize, o: *const i32, v: *mut f64, nv: usize);
    fmi3ActivateModelPartition(r: u32, t: f64);
}
