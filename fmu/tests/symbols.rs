//! The built shared library exports FMI 3.0's co-simulation functions under their C names (what
//! a master such as FMPy looks up when it loads the plant FMU).

use std::path::PathBuf;

/// target/<profile>/deps/, beside this test: cargo builds the cdylib there for this test (it
/// copies it up to target/<profile>/ only when it is built by name, `cargo build -p cncsim-fmu`).
fn library() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent()
        .unwrap()
        .join(cncsim::fmi::export::library_file())
}

#[test]
fn exports_the_fmi3_functions_by_their_c_names() {
    let path = library();
    assert!(path.is_file(), "{} was not built", path.display());
    // SAFETY: our own library; loading runs no code of consequence.
    let lib = unsafe { libloading::Library::new(&path) }.unwrap();
    for name in [
        "fmi3GetVersion",
        "fmi3InstantiateCoSimulation",
        "fmi3InstantiateModelExchange",
        "fmi3FreeInstance",
        "fmi3EnterInitializationMode",
        "fmi3ExitInitializationMode",
        "fmi3GetFloat64",
        "fmi3SetFloat64",
        "fmi3DoStep",
        "fmi3Terminate",
        "fmi3Reset",
        "fmi3GetClock",
        "fmi3GetOutputDerivatives",
        "fmi3UpdateDiscreteStates",
    ] {
        // SAFETY: only looked up, not called.
        let found = unsafe { lib.get::<*const ()>(name.as_bytes()) };
        assert!(found.is_ok(), "{name} is not exported");
    }
    // SAFETY: fmi3GetVersion takes nothing and returns a static string.
    let version = unsafe {
        let f = lib
            .get::<unsafe extern "C" fn() -> *const std::ffi::c_char>(b"fmi3GetVersion")
            .unwrap();
        std::ffi::CStr::from_ptr(f()).to_str().unwrap().to_string()
    };
    assert_eq!(version, "3.0");
}
