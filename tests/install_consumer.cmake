# Installs the built project into a scratch prefix, then configures, builds and runs a
# tiny consumer that uses find_package(tearables) and tearables::tearables.
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
# The package needs only what its installed headers need: no nlohmann_json (the scene
# loader's private JSON parser); the scene format is installed with the docs.
file(GLOB_RECURSE package_files ${WORK_DIR}/prefix/*.cmake)
foreach(f ${package_files})
  file(READ ${f} text)
  if(text MATCHES "nlohmann")
    message(FATAL_ERROR "${f} names nlohmann_json: find_package(tearables) would need it")
  endif()
endforeach()
file(GLOB_RECURSE scene_format ${WORK_DIR}/prefix/*/SCENE_FORMAT.md)
if(NOT scene_format)
  message(FATAL_ERROR "SCENE_FORMAT.md is not installed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S ${CONSUMER_DIR} -B ${WORK_DIR}/build
                        -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=Release
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the consumer failed (${rc})")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build -j2 RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building the consumer failed (${rc})")
endif()
execute_process(COMMAND ${WORK_DIR}/build/consumer RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message(STATUS "${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the consumer failed (${rc})")
endif()
