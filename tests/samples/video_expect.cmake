# Runs drape-run (CMD with ARGS, a ;-list) so that it renders frames and calls the real ffmpeg,
# then checks frames.mp4 under OUT with the real ffprobe (FFPROBE): one H.264 (yuv420p) video
# stream of EXPECT_WIDTH x EXPECT_HEIGHT holding exactly EXPECT_FRAMES decoded frames, and as
# many PNG frames on disk. With MISSING set (ffmpeg or ffprobe not found at configure time)
# it fails at once and says what to install.
if(DEFINED MISSING)
    message(FATAL_ERROR "${MISSING} not found when this build was configured: the video test "
        "needs Debian's ffmpeg (run scripts/setup.sh, or apt-get install ffmpeg, then re-run cmake)")
endif()
file(REMOVE_RECURSE "${OUT}")
execute_process(COMMAND ${CMD} ${ARGS}
    RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 300)
if(NOT code EQUAL 0)
    message(FATAL_ERROR "drape-run exit code ${code}\nstdout:\n${out}\nstderr:\n${err}")
endif()
set(mp4 "${OUT}/frames.mp4")
if(NOT out MATCHES "video +[^\n]*frames\\.mp4")
    message(FATAL_ERROR "drape-run did not report a video:\n${out}\nstderr:\n${err}")
endif()
if(NOT EXISTS "${mp4}")
    message(FATAL_ERROR "missing ${mp4}")
endif()
file(GLOB pngs "${OUT}/frames/frame_*.png")
list(LENGTH pngs png_count)
if(NOT png_count EQUAL EXPECT_FRAMES)
    message(FATAL_ERROR "${png_count} PNG frames in ${OUT}/frames, expected ${EXPECT_FRAMES}")
endif()
execute_process(COMMAND ${FFPROBE} -v error -count_frames -select_streams v
        -show_entries stream=codec_name,pix_fmt,width,height,nb_read_frames
        -of default=noprint_wrappers=1 "${mp4}"
    RESULT_VARIABLE code OUTPUT_VARIABLE probe ERROR_VARIABLE err TIMEOUT 120)
if(NOT code EQUAL 0)
    message(FATAL_ERROR "ffprobe failed (${code}) on ${mp4}:\n${err}")
endif()
string(REGEX MATCHALL "codec_name=" streams "${probe}")
list(LENGTH streams stream_count)
if(NOT stream_count EQUAL 1)
    message(FATAL_ERROR "${mp4}: expected one video stream, ffprobe says:\n${probe}")
endif()
foreach(pair "codec_name=h264" "pix_fmt=yuv420p" "width=${EXPECT_WIDTH}"
             "height=${EXPECT_HEIGHT}" "nb_read_frames=${EXPECT_FRAMES}")
    if(NOT probe MATCHES "(^|\n)${pair}(\n|$)")
        message(FATAL_ERROR "${mp4}: expected ${pair}, ffprobe says:\n${probe}")
    endif()
endforeach()
message(STATUS "ffprobe ${mp4}:\n${probe}")
