// Exception handler (Try): a failure on one drone cancels the whole Body.
// Drone1 flies a long leg north while Drone2 hops east, climbs 2 m and hops
// again.  If any of these actions fails (say Drone2's vehicle rejects the
// climb: tests/virtual/try_reject.toml makes the simulator do so), the Try
// catches it: Drone1's leg is cancelled mid-flight (it holds where it is), the
// rest of Body is skipped on both drones, and PAR_Recover flies both back.
// The mission goes on and ends normally; the summary lists the rejected
// action with the result "caught".  Without a failure, PAR_Recover is skipped.
package TryRescue

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Start()
	Try(PAR_Survey, PAR_Recover)
	PAR_Down()
}

func PAR_Start() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(3)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(3)
}

func PAR_Survey() {
	SEQ_Leg1()
	SEQ_Leg2()
}

func SEQ_Leg1() {
	Drone1.FlyByX(30)
	Drone1.FlyByY(5)
}

func SEQ_Leg2() {
	Drone2.FlyByY(3)
	Drone2.FlyByZ(2)
	Drone2.FlyByY(3)
}

func PAR_Recover() {
	Drone1.FlyToXYZ(0, 0, 3)
	Drone2.FlyToXYZ(0, 4, 3)
}

func PAR_Down() {
	SEQ_Down1()
	SEQ_Down2()
}

func SEQ_Down1() {
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Down2() {
	Drone2.Land()
	Drone2.Disarm()
}
