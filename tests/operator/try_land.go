// The operator lands Drone2 in the middle of a Try's Body (tests/operator/test_take_out.py):
// its FlyByY fails "landed by the operator", the Try catches it, Drone1's long leg is
// cancelled and OnFailure flies Drone1 back above home before it lands.
package TryLand

var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Mission() {
	PAR_Up()
	Try(PAR_Survey, SEQ_Recover)
	PAR_Down()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	Drone1.Arm()
	Drone1.Takeoff(2)
}

func SEQ_Up2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
}

func PAR_Survey() {
	Drone1.FlyByX(30)
	Drone2.FlyByY(30)
}

func SEQ_Recover() {
	Drone1.FlyToXYZ(0, 0, 2)
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
