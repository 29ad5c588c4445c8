//! The name of the machine a run was timed on (results name it: a sharded
//! sweep runs on many) and that holds the reference cache's lock.

/// This machine's host name (the system's, else `$HOSTNAME`, else
/// `unknown`), looked up once.
pub fn host_name() -> String {
    static HOST: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    HOST.get_or_init(|| {
        gethostname::gethostname()
            .into_string()
            .ok()
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .or_else(|| std::env::var("HOSTNAME").ok().filter(|s| !s.is_empty()))
            .unwrap_or_else(|| "unknown".into())
    })
    .clone()
}
