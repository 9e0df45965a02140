// The resolver behind the stubs of cmake/lazy_library_stubs.sh (obsynth executable only):
// loads FLINT and Arb on the first call of any of their functions, and points every stub's
// slot at the real function. Start-up then skips their ~10,000 immediate symbol bindings,
// which a `check` of a small model (no FLINT call) would otherwise pay for.
#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>

extern "C" {
extern void* obsynth_lazy_slots[];
extern const char* const obsynth_lazy_names[];
extern const int obsynth_lazy_count;
void* obsynth_lazy_resolve(int index);
}

namespace {

[[noreturn]] void cannot_load(const char* what) {
  const char* why = dlerror();
  std::fprintf(stderr, "obsynth: internal error: cannot load %s: %s\n", what, why ? why : "?");
  std::fflush(stderr);
  std::abort();  // after a failed allocation (ENOMEM) the worker reports a memory stop
}

// dlopen of Arb also maps FLINT (its dependency), and dlsym on Arb's handle searches both.
bool load_all() {
  void* flint = dlopen(OBSYNTH_LAZY_FLINT_SONAME, RTLD_NOW | RTLD_GLOBAL);
  if (!flint) cannot_load(OBSYNTH_LAZY_FLINT_SONAME);
  void* arb = dlopen(OBSYNTH_LAZY_ARB_SONAME, RTLD_NOW | RTLD_GLOBAL);
  if (!arb) cannot_load(OBSYNTH_LAZY_ARB_SONAME);
  for (int i = 0; i < obsynth_lazy_count; ++i) {
    void* f = dlsym(arb, obsynth_lazy_names[i]);
    if (!f) cannot_load(obsynth_lazy_names[i]);
    obsynth_lazy_slots[i] = f;
  }
  return true;
}

}  // namespace

extern "C" void* obsynth_lazy_resolve(int index) {
  static const bool loaded = load_all();  // thread-safe, once
  (void)loaded;
  return obsynth_lazy_slots[index];
}
