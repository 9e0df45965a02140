// The generated header compiles alone (it is the first include) under the contract flags,
// instantiated for float and double.
#include OBSYNTH_CANONICAL_HEADER
#include OBSYNTH_REFERENCE_HEADER

template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<float>;
template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<double>;
template struct obsynth_gen::OBSYNTH_NS::CanonicalFunctions<float>;
template struct obsynth_gen::OBSYNTH_NS::CanonicalFunctions<double>;
