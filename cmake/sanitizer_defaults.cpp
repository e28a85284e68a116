// Default sanitizer options for the sanitizer build's executables (linked in only when DUPLEXFIT_SANITIZE is
// set; the ASAN_OPTIONS / LSAN_OPTIONS environment variables still override each option).
//
// intercept_tls_get_addr=0: up to GCC 13 and LLVM 16, the runtime's __tls_get_addr interceptor takes a
// dynamic TLS block whose start is 16 bytes past a page boundary for a pre-2.25 glibc block with a header,
// and reads the header's words as the block's bounds. Such blocks appear by chance in the libraries the
// OpenCL loader opens (PoCL and LLVM), and the leak checker's tracer then faults at exit ("Tracer caught
// signal 11", "LeakSanitizer has encountered a fatal error"), an intermittent failure of the CLI's test runs
// that is not a leak. Debian 12's GCC 12 and glibc 2.36 are both affected.

extern "C" {

// NOLINTNEXTLINE(readability-identifier-naming): the names the sanitizer runtimes look up
const char* __asan_default_options();
const char* __lsan_default_options();

const char* __asan_default_options() { return "intercept_tls_get_addr=0"; }
const char* __lsan_default_options() { return "intercept_tls_get_addr=0"; }

}
