// Errors of the simulation core. Every error names the field, key or input that was wrong.
//
//   SimError (std::invalid_argument)          base of every error the sim core throws on bad input
//    ├─ SceneError                            a scene spec or scene file field ("hold point 0 ...")
//    ├─ ClothModelError                       unknown model name, bad model option ("model.jacobian ...")
//    └─ MemoryBudgetError                     a simulation above its memory budget (memory_budget.h)
// std::invalid_argument is the base so that callers that catch it keep working. Failures of files
// rather than of input derive from std::runtime_error: MaterialError (material.h, a material file or
// text), OutputError (output_files.h, an output that cannot be written).
#pragma once

#include <stdexcept>
#include <string>

namespace textile_handling {

class SimError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

class SceneError : public SimError {
 public:
  using SimError::SimError;
};

class ClothModelError : public SimError {
 public:
  using SimError::SimError;
};

}  // namespace textile_handling
