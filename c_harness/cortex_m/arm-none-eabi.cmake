# CMake toolchain file: arm-none-eabi-gcc for a bare-metal Cortex-M (Debian: gcc-arm-none-eabi,
# libnewlib-arm-none-eabi). Cortex-M4F by default; for a Cortex-M7 with its double FPU:
#   cmake -DCMAKE_TOOLCHAIN_FILE=arm-none-eabi.cmake \
#         -DARM_CPU_FLAGS="-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard" ...
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)  # test programs cannot link without startup code
set(ARM_CPU_FLAGS "-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard" CACHE STRING "CPU, FPU, ABI")
set(CMAKE_C_FLAGS_INIT "-mthumb ${ARM_CPU_FLAGS}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
