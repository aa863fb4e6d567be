import (
	"inspection"
	"lab/hover"
	"shapes"
)

var D1 Quadcopter

func SEQ_Main() {
	D1.Arm()
	D1.Takeoff(2)
	inspection.SEQ_Look(D1, 3)
	hover.SEQ_Wait(D1, 1)
	shapes.SEQ_Square(D1, 2)
	D1.Land()
	D1.Disarm()
}
