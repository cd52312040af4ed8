#!/bin/bash
# SPDX-License-Identifier: MIT
# Runs the hostile-input tests of docs/reliability.md from a build folder (the argument: this
# checkout's build/release, or a build of older code with these tests copied in, as that page
# describes), one test per process, under an 8 GB address-space cap and a 300 s limit, and prints
# one line per test: PASS, FAIL (its first failure line), or how it ended.
set -u
build=$1
run() {
  local program=$1 test=$2
  local out; out=$( (ulimit -v 8388608; timeout 300 "$build/$program" --gtest_filter="$test" 2>&1); echo "rc=$?")
  local rc; rc=$(echo "$out" | tail -1 | sed 's/rc=//')
  local what
  if [ "$rc" = 0 ]; then what="PASS"
  elif [ "$rc" = 124 ]; then what="TIMEOUT (300 s)"
  elif [ "$rc" -gt 128 ]; then what="KILLED by signal $((rc-128))"
  else what="FAIL: $(echo "$out" | grep -m1 -A1 -E 'Failure|Expected|exception|Value of' | tr '\n' ' ' | cut -c1-220)"; fi
  printf '%s\t%s\n' "$test" "$what"
}
for t in TheUneditedPackagesOpen NonFiniteFactorsAreRefusedWhenOpened HeaderIntegersMustBeExactAndInRange \
         MlvqExtentMustBeStatedAndAgree CodeBookSizesAreCheckedAgainstTheSectionBeforeAllocating \
         AnMlvqExtentLargerThanItsIndexSectionsIsRefusedBeforeAllocating \
         UndeclaredSectionsAndTrailingBytesAreRefused DirectionsMustLieOnTheHemisphere \
         DeclaredExtentsAndSectionsRespectTheLimits; do
  run codecs_tests "HostilePackage.$t"
done
for t in $("$build/io_tests" --gtest_list_tests --gtest_filter='Ubo2003Hostile.*' | grep '^  ' | tr -d ' '); do
  run io_tests "Ubo2003Hostile.$t"
done
run io_tests H5Test.DatasetsInOtherFilesAreRefusedUnlessAllowed
run io_tests H5Test.FilesThatCrashLibhdf5AreReportedNotFatal
run io_tests Ubo2014Test.FactorsThatOverflowTheColourModelAreRefusedWhereTheyEnter
[ -x "$build/bsvtf_tests" ] && run bsvtf_tests BsvtfFile.GroupsMustContinueTheirPlaneBeforeAnythingIsAllocated
for t in InterruptedRunLeavesNoFiles InterruptedCompressionLeavesNoFilesAndKeepsTheOldOutput AnHdf5FileThatCrashesLibhdf5GivesOneLine; do
  run cli_tests "BtfCli.$t"
done
