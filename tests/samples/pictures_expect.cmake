# The committed pictures are what scripts/pictures.sh renders now: runs the script (SCRIPT)
# with this build's programs (BIN) into OUT, then COMPARE (drape_compare_pictures) checks
# every PNG of OUT against COMMITTED (docs/pictures) pixel by pixel. With MISSING set (ffmpeg
# not found at configure time) it fails at once and says what to install.
if(DEFINED MISSING)
    message(FATAL_ERROR "${MISSING} not found when this build was configured: scripts/pictures.sh "
        "needs Debian's ffmpeg (run scripts/setup.sh, or apt-get install ffmpeg, then re-run cmake)")
endif()
file(REMOVE_RECURSE "${OUT}")
execute_process(COMMAND bash ${SCRIPT} --bin ${BIN} --out ${OUT}
    RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 600)
if(NOT code EQUAL 0)
    message(FATAL_ERROR "scripts/pictures.sh --bin ${BIN} --out ${OUT}: exit code ${code}\n"
        "stdout:\n${out}\nstderr:\n${err}")
endif()
execute_process(COMMAND ${COMPARE} ${COMMITTED} ${OUT}
    RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 120)
if(NOT code EQUAL 0)
    message(FATAL_ERROR "${out}${err}")
endif()
message(STATUS "${out}")
