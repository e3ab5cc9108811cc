// The config Reader and Registry: values in range, errors that name the JSON pointer and the valid choices.
#include "test_support.hpp"

#include <relit/config.hpp>

namespace relit {

using config::Reader;

namespace {
struct Thing {
  std::uint32_t width = 0;
  float lr = 0;
  std::string activation;
};

config::Registry<Thing> make_registry() {
  config::Registry<Thing> r("thing", "Plain");
  r.add("Plain", "a test component", [](Reader& rd) {
    auto t = std::make_unique<Thing>();
    t->width = rd.uint_choice("n_neurons", 64, {16, 32, 64, 128, 256}, "width");
    t->lr = rd.number("learning_rate", 0.01f, 0.0f, 1.0f, "step");
    t->activation = rd.choice("activation", "ReLU", {"None", "ReLU", "Sigmoid"}, "activation");
    return t;
  });
  return r;
}

std::string error_of(const Json& j) {
  try {
    make_registry().create(j, "/network");
  } catch (const ConfigError& e) {
    return std::string(e.what()) + " @" + e.pointer();
  }
  return "no error";
}
}  // namespace

TEST(Config, DefaultsAndResolvedHyperparameters) {
  Json resolved;
  auto t =
      make_registry().create(Json{{"otype", "plain"}, {"n_neurons", 128}, {"activation", "sigmoid"}}, "", &resolved);
  EXPECT_EQ(t->width, 128u);
  EXPECT_FLOAT_EQ(t->lr, 0.01f);
  EXPECT_EQ(t->activation, "Sigmoid");  // canonical spelling
  EXPECT_EQ(resolved,
            (Json{{"type", "Plain"}, {"n_neurons", 128}, {"learning_rate", 0.01f}, {"activation", "Sigmoid"}}));
  // Building from the resolved config gives the same thing.
  auto again = make_registry().create(resolved, "");
  EXPECT_EQ(again->width, 128u);
}

TEST(Config, ErrorsNameThePointerAndTheValidChoices) {
  EXPECT_EQ(error_of({{"n_neurons", 48}}),
            "/network/n_neurons: must be one of 16, 32, 64, 128, 256; got 48 @/network/n_neurons");
  EXPECT_EQ(error_of({{"n_neurons", "64"}}),
            "/network/n_neurons: must be one of 16, 32, 64, 128, 256; got \"64\" @/network/n_neurons");
  EXPECT_EQ(error_of({{"learning_rate", 2.0}}),
            "/network/learning_rate: must be in [0, 1], got 2.0 @/network/learning_rate");
  EXPECT_EQ(error_of({{"learning_rate", "fast"}}),
            "/network/learning_rate: must be a number in [0, 1], got a string \"fast\" @/network/learning_rate");
  EXPECT_EQ(error_of({{"n_neuron", 64}}),
            "/network/n_neuron: unknown key 'n_neuron' for Plain; valid keys: n_neurons, learning_rate, activation "
            "@/network/n_neuron");
  EXPECT_EQ(error_of({{"type", "Fancy"}}),
            "/network/type: unknown thing type 'Fancy'; valid types: Plain @/network/type");
  EXPECT_EQ(error_of({{"activation", "gelu"}}),
            "/network/activation: must be one of None, ReLU, Sigmoid; got \"gelu\" @/network/activation");
  EXPECT_EQ(error_of(Json::array()), "/network: thing config must be a JSON object, got [] @/network");
}

TEST(Config, UintRangesAndLists) {
  Reader r(Json{{"levels", 16}, {"skips", {4}}, {"bad", 1.5}, {"neg", -1}}, "/enc", "Test");
  EXPECT_EQ(r.uint("levels", 8, 1, 32, ""), 16u);
  EXPECT_EQ(r.uint_list("skips", {}, 1, 10, ""), std::vector<std::uint32_t>{4});
  EXPECT_THROW(r.uint("bad", 1, 0, 10, ""), ConfigError);
  EXPECT_THROW(r.uint("neg", 1, 0, 10, ""), ConfigError);
  EXPECT_NO_THROW(r.finish());
  Reader list(Json{{"skips", {4, 99}}}, "", "Test");
  try {
    list.uint_list("skips", {}, 1, 10, "");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.pointer(), "/skips/1");
  }
}

TEST(Config, DocsRecordEveryParameter) {
  Reader r(Json::object(), "", "Plain");
  r.uint_choice("n_neurons", 64, {16, 64}, "width of hidden layers");
  r.boolean("flag", true, "a flag");
  ASSERT_EQ(r.docs().size(), 2u);
  EXPECT_EQ(r.docs()[0].key, "n_neurons");
  EXPECT_EQ(r.docs()[0].valid, "16, 64");
  EXPECT_EQ(r.docs()[0].default_value, 64);
  EXPECT_EQ(r.docs()[1].description, "a flag");
}

}  // namespace relit
