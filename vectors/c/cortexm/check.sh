#!/usr/bin/env bash
# check.sh CORE OPT VEC BUILD [REGEX] -- build the C99 port with the golden vectors for one Cortex-M core and one
# optimisation level, run every batch under qemu-system-arm, and print the failures ("case <name> sample <i> word
# <W>: expected <x> got <y>") and one closing line "cortex-<core>-<opt>: N passed, M failed".  Exit 1 on any failure.
# CORE: m0 (BBC micro:bit, nRF51: 256 KiB flash, 16 KiB RAM), m3 (MPS2 AN385), m4 (MPS2 AN386: 4 MiB code, 4 MiB RAM).
# REGEX (optional) restricts the run to the cases whose name matches (grep -E syntax via Python re).
# Environment: CM_DEFS extra -D flags (e.g. -DFWV_ICOUNT for instruction counts), ARM_CC, QEMU.
set -u
core=$1; opt=$2; vec=$3; build=$4; regex=${5:-}
here=$(cd "$(dirname "$0")" && pwd)
src=$(cd "$here/.." && pwd)
ARM_CC=${ARM_CC:-arm-none-eabi-gcc}
QEMU=${QEMU:-qemu-system-arm}
case $core in
  m0) cpu=cortex-m0; machine=microbit; flash=256K; ram=16K; stack=4096; budget=224000; tick="-DFWV_TICK_NS_NUM=125 -DFWV_TICK_NS_DEN=2 -DFWV_ICOUNT_OVERSAMPLE=4" ;;
  m3) cpu=cortex-m3; machine=mps2-an385; flash=4M; ram=4M; stack=65536; budget=3900000; tick="-DFWV_TICK_NS_NUM=40 -DFWV_TICK_NS_DEN=1" ;;
  m4) cpu=cortex-m4; machine=mps2-an386; flash=4M; ram=4M; stack=65536; budget=3900000; tick="-DFWV_TICK_NS_NUM=40 -DFWV_TICK_NS_DEN=1" ;;
  *) echo "check.sh: unknown core '$core' (m0, m3, m4)" >&2; exit 2 ;;
esac
out="$build/cortex-$core-$opt"
mkdir -p "$out"
cpp -P -DFLASH_ORIGIN=0x00000000 -DFLASH_LENGTH=$flash -DRAM_ORIGIN=0x20000000 -DRAM_LENGTH=$ram \
    -DSTACK_SIZE=$stack "$here/board.ld.in" > "$out/board.ld" || exit 2
args=("$vec/c/cases.h" "$vec/cases" "$out/batches" "$budget")
[ -n "$regex" ] && args+=(--only "$regex")
python3 "$here/batches.py" "${args[@]}" || exit 2
passed=0; failed=0
while read -r batch count bytes; do
  elf="$out/${batch%.h}.elf"
  # shellcheck disable=SC2086
  if ! $ARM_CC -mcpu=$cpu -mthumb -$opt -std=c99 -Wall -Wextra -Werror -pedantic --specs=nano.specs \
        --specs=rdimon.specs -T "$out/board.ld" -Wl,--gc-sections ${CM_DEFS:-} $tick -I"$src" -I"$vec/cases" \
        -DFWV_CASES_FILE="\"$out/batches/$batch\"" "$here/startup.c" "$src/fw.c" "$src/harness.c" -o "$elf"; then
    echo "cortex-$core-$opt: $batch ($count cases, ~$bytes bytes) does not build or does not fit the board"
    failed=$((failed + count)); continue
  fi
  log="$out/${batch%.h}.log"
  timeout 120 "$QEMU" -M $machine -cpu $cpu -nographic -monitor none -serial none \
      -semihosting-config enable=on,target=native ${CM_QEMU_ARGS:-} -kernel "$elf" > "$log" 2>&1
  rc=$?
  grep -E '^(case |fault|cycles|icount|calibration)' "$log"
  line=$(grep -E '^[0-9]+ passed, [0-9]+ failed$' "$log" | tail -n 1)
  if [ -z "$line" ]; then
    echo "cortex-$core-$opt: $batch ended without a summary (qemu exit $rc): $(tail -n 3 "$log" | tr '\n' ' ')"
    failed=$((failed + count)); continue
  fi
  p=${line%% passed*}; f=${line#*, }; f=${f%% failed}
  passed=$((passed + p)); failed=$((failed + f))
  if [ "$f" = 0 ] && [ $rc != 0 ]; then
    echo "cortex-$core-$opt: $batch passed its cases but qemu exited $rc"; failed=$((failed + 1))
  fi
done < "$out/batches/batches.txt"
echo "cortex-$core-$opt: $passed passed, $failed failed"
[ "$failed" = 0 ]
