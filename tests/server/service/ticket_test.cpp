// A request's ticket: answered when the last stage holding it lets go, with its outcome, its error, or Busy when it
// was dropped unanswered.
#include "server/service/ticket.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <stdexcept>

namespace wm::service {
namespace {

using std::chrono::milliseconds;

TEST(TicketTest, TheAnswerLeavesWhenTheLastHolderLetsGo) {
  auto ticket = std::make_shared<Ticket<int>>();
  auto answer = ticket->future();
  auto grid_stage = ticket;  // the scan's grid insert still holds it
  ticket->succeed(7);
  ticket.reset();
  EXPECT_EQ(answer.wait_for(milliseconds(0)), std::future_status::timeout);
  grid_stage.reset();
  ASSERT_EQ(answer.wait_for(milliseconds(0)), std::future_status::ready);
  EXPECT_EQ(answer.get(), 7);
}

TEST(TicketTest, AnErrorWinsOverAnOutcome) {
  auto ticket = std::make_shared<Ticket<int>>();
  auto answer = ticket->future();
  ticket->succeed(7);
  ticket->fail(std::make_exception_ptr(std::runtime_error("not stored")));
  ticket.reset();
  EXPECT_THROW(answer.get(), std::runtime_error);
}

TEST(TicketTest, ATicketDroppedUnansweredIsBusy) {
  auto ticket = std::make_shared<Ticket<int>>();
  auto answer = ticket->future();
  ticket.reset();
  try {
    answer.get();
    FAIL() << "an unanswered ticket must not look applied";
  } catch (const Busy& e) {
    EXPECT_NE(std::string(e.what()).find("may have been applied"), std::string::npos);
  }
}

}  // namespace
}  // namespace wm::service
