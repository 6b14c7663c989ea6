// `JOINTSPACE_COMMIT` for `jointspace --version`: the plug-in library's build script, shared.
include!("../klipper/build.rs");
