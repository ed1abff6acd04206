//! The C functions of an FMU's shared library that a co-simulation master calls, FMI 3.0 and
//! FMI 2.0, loaded at run time, and one FMU instance behind a version-independent interface.

use super::description::FmiVersion;
use libloading::Library;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// FMI status codes (the same numbers in 2.0 and 3.0).
const OK: c_int = 0;
const WARNING: c_int = 1;

fn status_name(status: c_int) -> &'static str {
    match status {
        0 => "OK",
        1 => "Warning",
        2 => "Discard",
        3 => "Error",
        4 => "Fatal",
        5 => "Pending",
        _ => "an unknown status",
    }
}

type Instance = *mut c_void;
type Fmi3Log = unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char);

struct Fmi3Api {
    instantiate: unsafe extern "C" fn(
        *const c_char,
        *const c_char,
        *const c_char,
        bool,
        bool,
        bool,
        bool,
        *const u32,
        usize,
        *mut c_void,
        Option<Fmi3Log>,
        *const c_void,
    ) -> Instance,
    free: unsafe extern "C" fn(Instance),
    enter_initialization: unsafe extern "C" fn(Instance, bool, f64, f64, bool, f64) -> c_int,
    exit_initialization: unsafe extern "C" fn(Instance) -> c_int,
    set_float64: unsafe extern "C" fn(Instance, *const u32, usize, *const f64, usize) -> c_int,
    get_float64: unsafe extern "C" fn(Instance, *const u32, usize, *mut f64, usize) -> c_int,
    do_step: unsafe extern "C" fn(
        Instance,
        f64,
        f64,
        bool,
        *mut bool,
        *mut bool,
        *mut bool,
        *mut f64,
    ) -> c_int,
    reset: unsafe extern "C" fn(Instance) -> c_int,
    terminate: unsafe extern "C" fn(Instance) -> c_int,
}

/// FMI 2.0's logger is variadic (a printf format and its arguments); a non-variadic Rust
/// function receives the fixed arguments correctly on the platforms FMUs are built for, and
/// reports the format string as the message.
type Fmi2Log =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char);

#[repr(C)]
struct Fmi2Callbacks {
    logger: Fmi2Log,
    allocate_memory: unsafe extern "C" fn(usize, usize) -> *mut c_void,
    free_memory: unsafe extern "C" fn(*mut c_void),
    step_finished: *const c_void,
    component_environment: *mut c_void,
}

struct Fmi2Api {
    instantiate: unsafe extern "C" fn(
        *const c_char,
        c_int,
        *const c_char,
        *const c_char,
        *const Fmi2Callbacks,
        c_int,
        c_int,
    ) -> Instance,
    free: unsafe extern "C" fn(Instance),
    setup_experiment: unsafe extern "C" fn(Instance, c_int, f64, f64, c_int, f64) -> c_int,
    enter_initialization: unsafe extern "C" fn(Instance) -> c_int,
    exit_initialization: unsafe extern "C" fn(Instance) -> c_int,
    set_real: unsafe extern "C" fn(Instance, *const u32, usize, *const f64) -> c_int,
    get_real: unsafe extern "C" fn(Instance, *const u32, usize, *mut f64) -> c_int,
    do_step: unsafe extern "C" fn(Instance, f64, f64, c_int) -> c_int,
    reset: unsafe extern "C" fn(Instance) -> c_int,
    terminate: unsafe extern "C" fn(Instance) -> c_int,
}

enum Functions {
    Fmi3(Fmi3Api),
    Fmi2(Fmi2Api),
}

/// An FMU's loaded shared library and its co-simulation functions.
pub struct Api {
    functions: Functions,
    /// Kept loaded while any function pointer above may be called.
    _library: Library,
}

impl std::fmt::Debug for Api {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("fmi::Api")
    }
}

impl Api {
    /// Loads `library` and looks up every function the master calls.
    pub fn load(library: &Path, version: FmiVersion) -> Result<Api, String> {
        // SAFETY: loading runs the library's initialisers; an FMU's binary is code the user
        // chose to run, as the FMI standard intends.
        let lib = unsafe { Library::new(library) }
            .map_err(|e| format!("cannot load {}: {e}", library.display()))?;
        macro_rules! get {
            ($name:literal) => {
                // SAFETY: the signature is the one the FMI standard gives the symbol.
                *unsafe { lib.get($name.as_bytes()) }.map_err(|_| {
                    format!(
                        "{} does not export {} (required of an FMI {} co-simulation FMU)",
                        library.display(),
                        $name,
                        version.name()
                    )
                })?
            };
        }
        let functions = match version {
            FmiVersion::Fmi3 => Functions::Fmi3(Fmi3Api {
                instantiate: get!("fmi3InstantiateCoSimulation"),
                free: get!("fmi3FreeInstance"),
                enter_initialization: get!("fmi3EnterInitializationMode"),
                exit_initialization: get!("fmi3ExitInitializationMode"),
                set_float64: get!("fmi3SetFloat64"),
                get_float64: get!("fmi3GetFloat64"),
                do_step: get!("fmi3DoStep"),
                reset: get!("fmi3Reset"),
                terminate: get!("fmi3Terminate"),
            }),
            FmiVersion::Fmi2 => Functions::Fmi2(Fmi2Api {
                instantiate: get!("fmi2Instantiate"),
                free: get!("fmi2FreeInstance"),
                setup_experiment: get!("fmi2SetupExperiment"),
                enter_initialization: get!("fmi2EnterInitializationMode"),
                exit_initialization: get!("fmi2ExitInitializationMode"),
                set_real: get!("fmi2SetReal"),
                get_real: get!("fmi2GetReal"),
                do_step: get!("fmi2DoStep"),
                reset: get!("fmi2Reset"),
                terminate: get!("fmi2Terminate"),
            }),
        };
        Ok(Api {
            functions,
            _library: lib,
        })
    }
}

/// Messages an instance logged, kept for error reports.
#[derive(Default)]
struct Log {
    messages: Mutex<Vec<String>>,
}

impl Log {
    fn push(&self, status: c_int, category: *const c_char, message: *const c_char) {
        let text = |p: *const c_char| {
            if p.is_null() {
                String::new()
            } else {
                // SAFETY: FMI strings are NUL-terminated and valid during the callback.
                unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
            }
        };
        if let Ok(mut m) = self.messages.lock() {
            // Bounded: a chatty FMU must not grow memory over a long run.
            if m.len() >= 16 {
                m.remove(0);
            }
            m.push(format!(
                "[{}] {}{}",
                status_name(status),
                text(category),
                match text(message) {
                    t if t.is_empty() => String::new(),
                    t => format!(": {t}"),
                }
            ));
        }
    }

    fn take(&self) -> String {
        self.messages
            .lock()
            .map(|mut m| std::mem::take(&mut *m).join("; "))
            .unwrap_or_default()
    }
}

unsafe extern "C" fn log3(
    env: *mut c_void,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    if !env.is_null() {
        // SAFETY: `env` is the `Log` the instance was created with, alive as long as it.
        unsafe { &*(env as *const Log) }.push(status, category, message);
    }
}

unsafe extern "C" fn log2(
    env: *mut c_void,
    _instance: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: as log3.
    unsafe { log3(env, status, category, message) }
}

unsafe extern "C" fn allocate(count: usize, size: usize) -> *mut c_void {
    // SAFETY: calloc with the sizes the FMU asks for, as FMI 2.0 specifies.
    unsafe { libc_calloc(count, size) }
}

unsafe extern "C" fn free(p: *mut c_void) {
    // SAFETY: `p` came from `allocate`.
    unsafe { libc_free(p) }
}

extern "C" {
    #[link_name = "calloc"]
    fn libc_calloc(count: usize, size: usize) -> *mut c_void;
    #[link_name = "free"]
    fn libc_free(p: *mut c_void);
}

/// One instance of a co-simulation FMU. Calls check the status: anything but OK or Warning is
/// an error carrying what the FMU logged.
pub struct FmuInstance {
    api: Arc<Api>,
    handle: Instance,
    log: Box<Log>,
    /// FMI 2.0: the callbacks must outlive the instance.
    _callbacks: Option<Box<Fmi2Callbacks>>,
    initialized: bool,
}

impl FmuInstance {
    /// Instantiates the FMU for co-simulation. `resources` is the unpacked `resources/`
    /// folder.
    pub fn new(
        api: Arc<Api>,
        name: &str,
        token: &str,
        resources: &Path,
    ) -> Result<FmuInstance, String> {
        let log = Box::<Log>::default();
        let env = &*log as *const Log as *mut c_void;
        let c = |s: &str| CString::new(s).map_err(|_| format!("'{s}' contains a NUL byte"));
        let name_c = c(name)?;
        let token_c = c(token)?;
        let mut callbacks = None;
        let handle = match &api.functions {
            Functions::Fmi3(f) => {
                // FMI 3.0: the absolute path of resources/ with a trailing separator.
                let path = c(&format!("{}/", resources.display()))?;
                // SAFETY: arguments as the standard defines them; strings outlive the call.
                unsafe {
                    (f.instantiate)(
                        name_c.as_ptr(),
                        token_c.as_ptr(),
                        path.as_ptr(),
                        false,
                        false,
                        false,
                        false,
                        std::ptr::null(),
                        0,
                        env,
                        Some(log3 as Fmi3Log),
                        std::ptr::null(),
                    )
                }
            }
            Functions::Fmi2(f) => {
                // FMI 2.0: a file URI of resources/.
                let uri = c(&format!("file://{}/", resources.display()))?;
                let cb = Box::new(Fmi2Callbacks {
                    logger: log2,
                    allocate_memory: allocate,
                    free_memory: free,
                    step_finished: std::ptr::null(),
                    component_environment: env,
                });
                // SAFETY: as above; the callbacks are kept with the instance.
                let handle = unsafe {
                    (f.instantiate)(
                        name_c.as_ptr(),
                        1, // fmi2CoSimulation
                        token_c.as_ptr(),
                        uri.as_ptr(),
                        &*cb,
                        0,
                        0,
                    )
                };
                callbacks = Some(cb);
                handle
            }
        };
        if handle.is_null() {
            let said = log.take();
            return Err(format!(
                "instantiating it failed{}",
                if said.is_empty() {
                    String::new()
                } else {
                    format!(" ({said})")
                }
            ));
        }
        Ok(FmuInstance {
            api,
            handle,
            log,
            _callbacks: callbacks,
            initialized: false,
        })
    }

    fn check(&self, status: c_int, what: &str) -> Result<(), String> {
        if status == OK || status == WARNING {
            return Ok(());
        }
        let said = self.log.take();
        Err(format!(
            "{what} returned {}{}",
            status_name(status),
            if said.is_empty() {
                String::new()
            } else {
                format!(" ({said})")
            }
        ))
    }

    /// Enters and leaves initialization mode at `start_time` (parameters set before are used).
    pub fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        let h = self.handle;
        match &self.api.functions {
            Functions::Fmi3(f) => {
                // SAFETY: a live instance.
                let s = unsafe { (f.enter_initialization)(h, false, 0.0, start_time, false, 0.0) };
                self.check(s, "fmi3EnterInitializationMode")?;
                let s = unsafe { (f.exit_initialization)(h) };
                self.check(s, "fmi3ExitInitializationMode")?;
            }
            Functions::Fmi2(f) => {
                // SAFETY: a live instance.
                let s = unsafe { (f.setup_experiment)(h, 0, 0.0, start_time, 0, 0.0) };
                self.check(s, "fmi2SetupExperiment")?;
                let s = unsafe { (f.enter_initialization)(h) };
                self.check(s, "fmi2EnterInitializationMode")?;
                let s = unsafe { (f.exit_initialization)(h) };
                self.check(s, "fmi2ExitInitializationMode")?;
            }
        }
        self.initialized = true;
        Ok(())
    }

    /// Sets 64-bit float variables.
    pub fn set(&mut self, references: &[u32], values: &[f64]) -> Result<(), String> {
        debug_assert_eq!(references.len(), values.len());
        let (h, n) = (self.handle, references.len());
        // SAFETY: both slices hold `n` elements.
        let s = match &self.api.functions {
            Functions::Fmi3(f) => unsafe {
                (f.set_float64)(h, references.as_ptr(), n, values.as_ptr(), n)
            },
            Functions::Fmi2(f) => unsafe {
                (f.set_real)(h, references.as_ptr(), n, values.as_ptr())
            },
        };
        self.check(s, "setting inputs")
    }

    /// Reads 64-bit float variables.
    pub fn get(&mut self, references: &[u32], values: &mut [f64]) -> Result<(), String> {
        debug_assert_eq!(references.len(), values.len());
        let (h, n) = (self.handle, references.len());
        // SAFETY: both slices hold `n` elements.
        let s = match &self.api.functions {
            Functions::Fmi3(f) => unsafe {
                (f.get_float64)(h, references.as_ptr(), n, values.as_mut_ptr(), n)
            },
            Functions::Fmi2(f) => unsafe {
                (f.get_real)(h, references.as_ptr(), n, values.as_mut_ptr())
            },
        };
        self.check(s, "reading outputs")
    }

    /// Advances from `time` by `step`. An FMU that returns early or asks to terminate has
    /// not done the step, which is an error here (the controller runs on a fixed period).
    pub fn do_step(&mut self, time: f64, step: f64) -> Result<(), String> {
        let h = self.handle;
        match &self.api.functions {
            Functions::Fmi3(f) => {
                let (mut event, mut terminate, mut early) = (false, false, false);
                let mut last = time;
                // SAFETY: a live instance; the out-pointers are valid.
                let s = unsafe {
                    (f.do_step)(
                        h,
                        time,
                        step,
                        true,
                        &mut event,
                        &mut terminate,
                        &mut early,
                        &mut last,
                    )
                };
                self.check(s, "fmi3DoStep")?;
                if terminate {
                    return Err("fmi3DoStep asked to terminate the simulation".into());
                }
                if early {
                    return Err(format!(
                        "fmi3DoStep returned early at t = {last} s (early return is not supported)"
                    ));
                }
                Ok(())
            }
            Functions::Fmi2(f) => {
                // SAFETY: a live instance.
                let s = unsafe { (f.do_step)(h, time, step, 1) };
                self.check(s, "fmi2DoStep")
            }
        }
    }

    /// Returns the instance to its state after instantiation.
    pub fn reset(&mut self) -> Result<(), String> {
        let h = self.handle;
        // SAFETY: a live instance.
        let s = match &self.api.functions {
            Functions::Fmi3(f) => unsafe { (f.reset)(h) },
            Functions::Fmi2(f) => unsafe { (f.reset)(h) },
        };
        self.initialized = false;
        self.check(s, "reset")
    }
}

impl Drop for FmuInstance {
    fn drop(&mut self) {
        let h = self.handle;
        // SAFETY: a live instance, freed once; errors at the end are of no use to anyone.
        unsafe {
            match &self.api.functions {
                Functions::Fmi3(f) => {
                    if self.initialized {
                        (f.terminate)(h);
                    }
                    (f.free)(h);
                }
                Functions::Fmi2(f) => {
                    if self.initialized {
                        (f.terminate)(h);
                    }
                    (f.free)(h);
                }
            }
        }
    }
}
