//! Puts `memory.x` and the device's `device.x` where the linker finds them, and checks that
//! `PIL_CONFIG` names the scenario's configuration (`plant_sim pil-config`).
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), include_bytes!("memory.x")).expect("write memory.x");
    fs::write(out.join("device.x"), include_bytes!("device.x")).expect("write device.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=device.x");
    println!("cargo:rerun-if-env-changed=PIL_CONFIG");
    match env::var("PIL_CONFIG") {
        Ok(p) if PathBuf::from(&p).is_file() => println!("cargo:rerun-if-changed={p}"),
        Ok(p) => panic!("PIL_CONFIG={p}: no such file (write it with plant_sim pil-config)"),
        Err(_) => panic!(
            "PIL_CONFIG is not set: the firmware needs a scenario's configuration (plant_sim pil-config --scenario FILE --out FILE)"
        ),
    }
}
