// The generated Thau/Kou header compiles alone (it is the first include) under the contract
// flags, instantiated for float and double (with EIGEN_NO_MALLOC from CMake).
#include OBSYNTH_HEADER
#include OBSYNTH_REFERENCE_HEADER

template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<float>;
template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<double>;
template struct obsynth_gen::OBSYNTH_NS::OBSYNTH_FUNCTIONS<float>;
template struct obsynth_gen::OBSYNTH_NS::OBSYNTH_FUNCTIONS<double>;
