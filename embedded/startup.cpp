// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Minimal Cortex-M4F start-up for qemu-system-arm -M mps2-an386 with newlib semihosting.
//
// - Vector table (section .vectors, placed at 0 by mps2-an386.ld): initial SP, reset handler,
//   fault handlers. Interrupts are never enabled, so the remaining vectors are a catch-all.
// - Reset handler: enables the FPU (CPACR CP10/CP11 full access, bits 20-23) *before* any
//   floating-point instruction can run, then jumps to newlib's _start (rdimon crt0), which sets
//   up the stack and heap via semihosting, zeroes .bss, runs constructors, calls main and exits
//   with main's return value through semihosting (QEMU then exits with that status).
// - Fault handlers: print which fault, CFSR/HFSR and the stacked PC through semihosting and
//   exit with status 1 (never hang, so a crash fails a test instead of timing out).
//
// Nothing here uses floating point or the C library, so it runs before either is set up.
#include <cstdint>

extern "C" {
[[noreturn]] void _start();  // newlib crt0 (rdimon-crt0.o)
[[noreturn]] void mps2_reset_handler();
void mps2_fault_handler();
extern std::uint32_t __stack;  // from the linker script
}

namespace {

constexpr std::uint32_t kSysWrite0 = 0x04;       // semihosting SYS_WRITE0
constexpr std::uint32_t kSysExit = 0x18;         // semihosting SYS_EXIT (angel_SWIreason_ReportException)
constexpr std::uint32_t kSysExitExtended = 0x20; // semihosting SYS_EXIT_EXTENDED
constexpr std::uint32_t kAdpStoppedApplicationExit = 0x20026;
constexpr std::uint32_t kAdpStoppedRunTimeError = 0x20023;

inline std::uint32_t semihost(std::uint32_t op, const void* arg) {
  register std::uint32_t r0 __asm__("r0") = op;
  register const void* r1 __asm__("r1") = arg;
  __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

void write_str(const char* s) { semihost(kSysWrite0, s); }

void write_hex(const char* label, std::uint32_t v) {
  char buf[32];
  int i = 0;
  for (const char* p = label; *p != '\0' && i < 16; ++p) buf[i++] = *p;
  buf[i++] = '0';
  buf[i++] = 'x';
  for (int shift = 28; shift >= 0; shift -= 4) {
    const std::uint32_t nib = (v >> static_cast<unsigned>(shift)) & 0xFu;
    buf[i++] = static_cast<char>(nib < 10u ? '0' + static_cast<int>(nib)
                                           : 'a' + static_cast<int>(nib) - 10);
  }
  buf[i++] = '\n';
  buf[i] = '\0';
  write_str(buf);
}

[[noreturn]] void semihost_exit_failure() {
  // SYS_EXIT_EXTENDED carries an exit code; plain SYS_EXIT with a run-time-error reason makes
  // QEMU exit with status 1 as a fall-back.
  const std::uint32_t block[2] = {kAdpStoppedApplicationExit, 1u};
  semihost(kSysExitExtended, block);
  semihost(kSysExit, reinterpret_cast<const void*>(static_cast<std::uintptr_t>(kAdpStoppedRunTimeError)));
  for (;;) {
  }
}

volatile std::uint32_t& reg(std::uint32_t addr) {
  return *reinterpret_cast<volatile std::uint32_t*>(static_cast<std::uintptr_t>(addr));
}

}  // namespace

extern "C" [[noreturn]] void mps2_reset_handler() {
  // CPACR (0xE000ED88): CP10 and CP11 full access.
  reg(0xE000ED88u) = reg(0xE000ED88u) | (0xFu << 20);
  __asm__ volatile("dsb\n\tisb" ::: "memory");
  _start();
}

// Common fault entry: r0 = active stack pointer at the fault (stacked frame), so the stacked
// PC is at frame[6].
extern "C" void mps2_fault_report(const std::uint32_t* frame) {
  const std::uint32_t ipsr_vector = [] {
    std::uint32_t v;
    __asm__ volatile("mrs %0, ipsr" : "=r"(v));
    return v & 0x1FFu;
  }();
  write_str("\n*** obsynth embedded: fault, exception number ");
  const char* names[] = {"?", "?", "NMI", "HardFault", "MemManage", "BusFault", "UsageFault"};
  write_str(ipsr_vector < 7u ? names[ipsr_vector] : "unexpected interrupt");
  write_str(" ***\n");
  write_hex("CFSR  = ", reg(0xE000ED28u));
  write_hex("HFSR  = ", reg(0xE000ED2Cu));
  write_hex("MMFAR = ", reg(0xE000ED34u));
  write_hex("BFAR  = ", reg(0xE000ED38u));
  if (frame != nullptr) {
    write_hex("PC    = ", frame[6]);
    write_hex("LR    = ", frame[5]);
  }
  semihost_exit_failure();
}

extern "C" __attribute__((naked)) void mps2_fault_handler() {
  __asm__ volatile(
      "tst lr, #4\n\t"
      "ite eq\n\t"
      "mrseq r0, msp\n\t"
      "mrsne r0, psp\n\t"
      "b mps2_fault_report\n\t");
}

using Vector = void (*)();

// Cortex-M vector table: [0] initial SP, [1] reset, [2] NMI, [3] HardFault, [4] MemManage,
// [5] BusFault, [6] UsageFault, [7-10] reserved, [11] SVCall, [12] DebugMon, [13] reserved,
// [14] PendSV, [15] SysTick, then 16 external interrupts (more than enough: none are enabled).
extern "C" __attribute__((section(".vectors"), used)) const Vector mps2_vector_table[32] = {
    reinterpret_cast<Vector>(&__stack),
    mps2_reset_handler,
    mps2_fault_handler,  // NMI
    mps2_fault_handler,  // HardFault
    mps2_fault_handler,  // MemManage
    mps2_fault_handler,  // BusFault
    mps2_fault_handler,  // UsageFault
    nullptr,
    nullptr,
    nullptr,
    nullptr,
    mps2_fault_handler,  // SVCall
    mps2_fault_handler,  // DebugMon
    nullptr,
    mps2_fault_handler,  // PendSV
    mps2_fault_handler,  // SysTick
    mps2_fault_handler, mps2_fault_handler, mps2_fault_handler, mps2_fault_handler,
    mps2_fault_handler, mps2_fault_handler, mps2_fault_handler, mps2_fault_handler,
    mps2_fault_handler, mps2_fault_handler, mps2_fault_handler, mps2_fault_handler,
    mps2_fault_handler, mps2_fault_handler, mps2_fault_handler, mps2_fault_handler,
};
