#!/usr/bin/env bash
# check.sh CORE OPT VEC BUILD [REGEX] -- build the C99 port with the golden vectors for one MCU core and one
# optimisation level, run every batch under its simulator, and print the failures ("case <name> sample <i> word
# <W>: expected <x> got <y>") and one closing line "<target>: N passed, M failed".  Exit 1 on any failure.
# CORE: m0 (BBC micro:bit, nRF51: 256 KiB flash, 16 KiB RAM), m3 (MPS2 AN385), m4 (MPS2 AN386: 4 MiB code, 4 MiB RAM)
#       under qemu-system-arm with semihosting; avr (ATmega2560 @ 16 MHz under simavr: 256 KiB flash, but the
#       PROGMEM reads use 16-bit addresses, so a batch holds at most ~56 KB of vector data; 8 KiB RAM).
# REGEX (optional) restricts the run to the cases whose name matches (grep -E syntax via Python re).
# Environment: CM_DEFS extra -D flags (e.g. -DFWV_ICOUNT for instruction counts), CM_QEMU_ARGS, ARM_CC, QEMU,
# AVR_CC, SIMAVR.
set -u
core=$1; opt=$2; vec=$3; build=$4; regex=${5:-}
here=$(cd "$(dirname "$0")" && pwd)
src=$(cd "$here/.." && pwd)
ARM_CC=${ARM_CC:-arm-none-eabi-gcc}
QEMU=${QEMU:-qemu-system-arm}
AVR_CC=${AVR_CC:-avr-gcc}
SIMAVR=${SIMAVR:-simavr}
case $core in
  m0) cpu=cortex-m0; machine=microbit; flash=256K; ram=16K; stack=4096; budget=224000; tick="-DFWV_TICK_NS_NUM=125 -DFWV_TICK_NS_DEN=2 -DFWV_ICOUNT_OVERSAMPLE=4" ;;
  m3) cpu=cortex-m3; machine=mps2-an385; flash=4M; ram=4M; stack=65536; budget=3900000; tick="-DFWV_TICK_NS_NUM=40 -DFWV_TICK_NS_DEN=1" ;;
  m4) cpu=cortex-m4; machine=mps2-an386; flash=4M; ram=4M; stack=65536; budget=3900000; tick="-DFWV_TICK_NS_NUM=40 -DFWV_TICK_NS_DEN=1" ;;
  avr) budget=56000; split="--max-object 32000" ;;
  *) echo "check.sh: unknown core '$core' (m0, m3, m4, avr)" >&2; exit 2 ;;
esac
if [ "$core" = avr ]; then target="avr-$opt"; else target="cortex-$core-$opt"; fi
out="$build/$target"
mkdir -p "$out"
[ "$core" = avr ] || cpp -P -DFLASH_ORIGIN=0x00000000 -DFLASH_LENGTH=$flash -DRAM_ORIGIN=0x20000000 -DRAM_LENGTH=$ram \
    -DSTACK_SIZE=$stack "$here/board.ld.in" > "$out/board.ld" || exit 2
args=("$vec/c/cases.h" "$vec/cases" "$out/batches" "$budget")
[ -n "$regex" ] && args+=(--only "$regex")
# shellcheck disable=SC2206
[ -n "${split:-}" ] && args+=($split)
python3 "$here/batches.py" "${args[@]}" || exit 2
# A case fails when its batch does not build or run, or when the harness names it ("case <name>[ or :]...").
all_cases="$out/all.txt"; bad_cases="$out/failed.txt"
: > "$all_cases"; : > "$bad_cases"
extra=0
# fw.c and startup.c do not depend on the batch: compile them once per target with the very flags of the per-batch
# command, which then compiles only harness.c (the batch's data) and links in the same order (startup, fw, harness),
# so each ELF is the one a single all-sources command makes. If they do not compile, the sources are passed
# instead and every batch fails to build as before.
if [ "$core" = avr ]; then
  fw_o="$out/fw.o"
  $AVR_CC -mmcu=atmega2560 -DF_CPU=16000000UL -std=c99 -Wall -Wextra -Werror -pedantic -$opt -I"$src" \
      -I"$vec/cases" -c "$src/fw.c" -o "$fw_o" || fw_o="$src/fw.c"
  objs=("$fw_o")
else
  start_o="$out/startup.o"; fw_o="$out/fw.o"
  # shellcheck disable=SC2086
  cm_c() { $ARM_CC -mcpu=$cpu -mthumb -$opt -std=c99 -Wall -Wextra -Werror -pedantic --specs=nano.specs \
               --specs=rdimon.specs ${CM_DEFS:-} $tick -I"$src" -I"$vec/cases" -c "$1" -o "$2"; }
  cm_c "$here/startup.c" "$start_o" || start_o="$here/startup.c"
  cm_c "$src/fw.c" "$fw_o" || fw_o="$src/fw.c"
  objs=("$start_o" "$fw_o")
fi
while read -r batch bytes names; do
  count=$(echo $names | wc -w)
  printf '%s\n' $names >> "$all_cases"
  elf="$out/${batch%.h}.elf"
  if [ "$core" = avr ]; then
    if ! $AVR_CC -mmcu=atmega2560 -DF_CPU=16000000UL -std=c99 -Wall -Wextra -Werror -pedantic -$opt -I"$src" \
          -I"$vec/cases" -DFWV_CASES_FILE="\"$out/batches/$batch\"" "${objs[@]}" "$src/harness.c" -o "$elf"; then
      echo "$target: $batch ($count cases, ~$bytes bytes) does not build or does not fit the board"
      printf '%s\n' $names >> "$bad_cases"; continue
    fi
    log="$out/${batch%.h}.log"
    # simavr's exit status does not reflect the program's: the log must end with "N passed, M failed".
    timeout 600 "$SIMAVR" -m atmega2560 -f 16000000 "$elf" 2>&1 | sed -e 's/\x1b\[[0-9;]*m//g' -e 's/\.$//' > "$log"
    rc=0
  # shellcheck disable=SC2086
  elif ! $ARM_CC -mcpu=$cpu -mthumb -$opt -std=c99 -Wall -Wextra -Werror -pedantic --specs=nano.specs \
        --specs=rdimon.specs -T "$out/board.ld" -Wl,--gc-sections ${CM_DEFS:-} $tick -I"$src" -I"$vec/cases" \
        -DFWV_CASES_FILE="\"$out/batches/$batch\"" "${objs[@]}" "$src/harness.c" -o "$elf"; then
    echo "$target: $batch ($count cases, ~$bytes bytes) does not build or does not fit the board"
    printf '%s\n' $names >> "$bad_cases"; continue
  else
  log="$out/${batch%.h}.log"
  timeout 120 "$QEMU" -M $machine -cpu $cpu -nographic -monitor none -serial none \
      -semihosting-config enable=on,target=native ${CM_QEMU_ARGS:-} -kernel "$elf" > "$log" 2>&1
  rc=$?
  fi
  grep -E '^(case |fault|cycles|icount|calibration)' "$log"
  grep -E '^case ' "$log" | sed -E 's/^case ([A-Za-z0-9_]+).*/\1/' >> "$bad_cases"
  line=$(grep -E '^[0-9]+ passed, [0-9]+ failed$' "$log" | tail -n 1)
  if [ -z "$line" ]; then
    echo "$target: $batch ended without a summary (exit $rc): $(tail -n 3 "$log" | tr '\n' ' ')"
    printf '%s\n' $names >> "$bad_cases"; continue
  fi
  f=${line#*, }; f=${f%% failed}
  if [ "$f" != 0 ] && ! grep -qE '^case ' "$log"; then
    echo "$target: $batch reports $f failures without naming a case"; extra=$((extra + f))
  fi
  if [ "$f" = 0 ] && [ $rc != 0 ]; then
    echo "$target: $batch passed its cases but the simulator exited $rc"; extra=$((extra + 1))
  fi
done < "$out/batches/batches.txt"
total=$(sort -u "$all_cases" | grep -c .)
failed=$(( $(sort -u "$bad_cases" | grep -c .) + extra ))
echo "$target: $((total - $(sort -u "$bad_cases" | grep -c .))) passed, $failed failed"
[ "$failed" = 0 ]
