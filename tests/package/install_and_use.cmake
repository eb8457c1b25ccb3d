# tests/package: installs drape from its build folder into a fresh prefix, checks that the
# installation is complete, then configures, builds and runs tests/package/consumer against
# it with find_package(drape CONFIG REQUIRED). Run by CTest after the build:
#   cmake -DBUILD_DIR=<drape build> -DCONFIG=<config> -DPREFIX=<empty folder to install into>
#         -DCONSUMER_SOURCE=<tests/package/consumer> -DCONSUMER_BUILD=<folder>
#         -DHEADER_DIRS=<source include folders, ;-list> -DGENERATOR=<generator>
#         -DCXX=<compiler> -DGARMENT=<an OBJ garment> -DRENDERING=<ON|OFF> [-DWERROR=ON]
#         -P install_and_use.cmake
# The consumer's drape_garment reads GARMENT through drape::io, runs it in a Bullet world with
# the default (automatic) sub-steps and writes it draped; the installed drape-run then renders
# a frame of that OBJ (RENDERING on) and the installed drape-check answers for it.
foreach(var BUILD_DIR CONFIG PREFIX CONSUMER_SOURCE CONSUMER_BUILD HEADER_DIRS GENERATOR CXX
        GARMENT RENDERING)
    if(NOT DEFINED ${var})
        message(FATAL_ERROR "install_and_use.cmake: -D${var}=... is required")
    endif()
endforeach()

function(run what)
    execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
    if(NOT code EQUAL 0)
        message(FATAL_ERROR "${what} failed (${code}):\n${ARGN}\n${out}\n${err}")
    endif()
    message(STATUS "${what}: ok")
    set(last_output "${out}" PARENT_SCOPE)
endfunction()

# A single-configuration build without a build type has an empty CONFIG.
set(config_args "")
set(build_type_arg "")
if(CONFIG)
    set(config_args --config ${CONFIG})
    set(build_type_arg -DCMAKE_BUILD_TYPE=${CONFIG})
endif()

# 1. Install into an empty prefix.
file(REMOVE_RECURSE ${PREFIX} ${CONSUMER_BUILD})
run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} ${config_args} --prefix ${PREFIX})

# 2. Every public header is there, and the CMake package files.
set(missing "")
foreach(dir ${HEADER_DIRS})
    file(GLOB_RECURSE headers RELATIVE ${dir} ${dir}/*.hpp)
    if(NOT headers)
        message(FATAL_ERROR "no headers found under ${dir}")
    endif()
    foreach(h ${headers})
        if(NOT EXISTS ${PREFIX}/include/${h})
            list(APPEND missing include/${h})
        endif()
    endforeach()
endforeach()
file(GLOB_RECURSE config_files ${PREFIX}/drapeConfig.cmake)
list(LENGTH config_files n)
if(NOT n EQUAL 1)
    message(FATAL_ERROR "expected one drapeConfig.cmake under ${PREFIX}, found: '${config_files}'")
endif()
get_filename_component(config_dir ${config_files} DIRECTORY)
foreach(program drape-run drape-check)
    if(NOT EXISTS ${PREFIX}/bin/${program})
        list(APPEND missing bin/${program})
    endif()
endforeach()
foreach(f drapeConfigVersion.cmake drapeTargets.cmake)
    if(NOT EXISTS ${config_dir}/${f})
        list(APPEND missing ${config_dir}/${f})
    endif()
endforeach()
if(missing)
    message(FATAL_ERROR "the installation in ${PREFIX} is incomplete; missing:\n  ${missing}")
endif()
message(STATUS "installed files: ok")

# 3. A separate project finds drape in the prefix (and nowhere else), builds and runs.
run("configure the consumer" ${CMAKE_COMMAND} -S ${CONSUMER_SOURCE} -B ${CONSUMER_BUILD}
    -G ${GENERATOR} -DCMAKE_CXX_COMPILER=${CXX} ${build_type_arg}
    -DCMAKE_PREFIX_PATH=${PREFIX} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
    -DCONSUMER_WERROR=${WERROR})
file(STRINGS ${CONSUMER_BUILD}/CMakeCache.txt drape_dir REGEX "^drape_DIR:")
string(REGEX REPLACE "^drape_DIR:[A-Z]+=" "" drape_dir "${drape_dir}")
file(REAL_PATH ${PREFIX} real_prefix)
file(REAL_PATH "${drape_dir}" real_drape_dir)
string(FIND "${real_drape_dir}" "${real_prefix}/" at)
if(NOT at EQUAL 0)
    message(FATAL_ERROR "the consumer found drape in '${drape_dir}', not under ${PREFIX}")
endif()
run("build the consumer" ${CMAKE_COMMAND} --build ${CONSUMER_BUILD} ${config_args})
file(GLOB_RECURSE program ${CONSUMER_BUILD}/drape_consumer ${CONSUMER_BUILD}/drape_consumer.exe)
if(NOT program)
    message(FATAL_ERROR "no drape_consumer program under ${CONSUMER_BUILD}")
endif()
list(GET program 0 program)
run("run the consumer" ${program})
message("${last_output}")

# 4. The artist's garment through drape::io, in a Bullet world with automatic sub-steps.
set(draped ${CONSUMER_BUILD}/skirt_draped.obj)
file(GLOB_RECURSE garment_program ${CONSUMER_BUILD}/drape_garment ${CONSUMER_BUILD}/drape_garment.exe)
if(NOT garment_program)
    message(FATAL_ERROR "no drape_garment program under ${CONSUMER_BUILD}")
endif()
list(GET garment_program 0 garment_program)
run("run the garment" ${garment_program} ${GARMENT} ${draped})
message("${last_output}")

# 5. The installed programs on the draped garment: a scene file naming it, one rendered frame.
set(scene ${CONSUMER_BUILD}/skirt_scene.json)
file(WRITE ${scene} "{
  \"name\": \"installed_runner\",
  \"cloth\": {\"mesh\": {\"file\": \"${draped}\"}, \"total_mass\": 0.2},
  \"simulation\": {\"time_step\": 0.01, \"duration\": 0.05, \"substeps\": \"auto\"},
  \"strain_limit\": {\"method\": \"stress_ordered\", \"max_strain\": 0.1},
  \"rigid_bodies\": [{\"name\": \"floor\", \"shape\": {\"type\": \"plane\", \"normal\": [0, 1, 0], \"offset\": 0.0}}],
  \"camera\": {\"position\": [1.5, 1.2, 1.5], \"target\": [0.4, 0.8, 0.0], \"width\": 160, \"height\": 120},
  \"output\": {\"fps\": 20}
}
")
set(run_out ${CONSUMER_BUILD}/runner_out)
file(REMOVE_RECURSE ${run_out})
run("installed drape-run" ${PREFIX}/bin/drape-run ${scene} -o ${run_out} --no-video --quiet)
if(NOT EXISTS ${run_out}/summary.txt OR NOT EXISTS ${run_out}/cloth_final.obj)
    message(FATAL_ERROR "the installed drape-run wrote no summary.txt or cloth_final.obj in ${run_out}")
endif()
if(RENDERING)
    file(GLOB frames ${run_out}/frames/*.png ${run_out}/*.png)
    if(NOT frames)
        message(FATAL_ERROR "the installed drape-run rendered no PNG frame in ${run_out}")
    endif()
    list(LENGTH frames n_frames)
    message(STATUS "installed drape-run: ${n_frames} PNG frame(s)")
endif()
run("installed drape-check" ${PREFIX}/bin/drape-check --scene ${scene})
message("${last_output}")
